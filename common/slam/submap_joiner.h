#pragma once
// Least-squares joining of local submaps (Huang, Wang & Dissanayake's I-SLSJF, as Downs uses
// it in chapter 3.1 and 4.3; here with each submap's full covariance, not an identity).
//
// Submap k is an estimate, in its own frame F_k, of the robot's pose at its end and of the
// landmarks it mapped, with their joint covariance. F_0 is the joined map's frame; the end
// pose of submap k is the origin of F_{k+1}. The joiner finds the frames' poses X_k and the
// landmarks L_j that minimise
//   sum_k || z_k - h_k(X_k, X_{k+1}, L) ||^2 over P_k^-1,
//   h_k = [ X_k^-1 * X_{k+1} ; X_k^-1(L_j) for each landmark j of submap k ],
// by Gauss-Newton with a sparse Cholesky factorisation, relinearising at every iteration: the
// error an EKF keeps from linearising at a poor estimate is undone here.
//
// The cost stays bounded as the run grows: only the last `window` submaps are relinearised.
// Older ones are marginalised (a Schur complement) into one Gaussian prior over the landmarks
// and the oldest frame still in the window, linearised where they were when they left. The
// state then holds every landmark and at most window + 1 frames, however long the run.
// A prior linearised at a poor estimate keeps its error however the later submaps disagree
// (MRCLAM 1 robot 5 at 3 deg submaps: one landmark 2.7 m off with a window of 8, 0.1 m with 32).
// With relinearise_m, the joiner keeps every submap and, when the estimate has moved that far
// from the prior's linearisation point, relinearises them all once and marginalises again.
//
// Pure: Eigen only, no clocks, threads or random numbers.

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <optional>
#include <unordered_map>
#include <vector>

#include "common/geometry/pose2.h"

namespace mapmesh {

// One submap: x = [end pose (x, y, theta); landmark means (2 each)] in the submap's frame,
// p = its covariance, keys = the landmarks' keys in the joined map (distinct), in x's order.
struct SubmapEstimate {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(3);
  Eigen::MatrixXd p = Eigen::MatrixXd::Identity(3, 3);
  std::vector<std::uint32_t> keys;
};

// What submap k measures, h_k above: [X_k^-1 * X_k+1 (x, y, theta); X_k^-1(L_j) for each j],
// and if asked its Jacobian with respect to [X_k, X_k+1, L_1, L_2, ...].
Eigen::VectorXd PredictSubmap(const Pose2& origin, const Pose2& end, const std::vector<Eigen::Vector2d>& landmarks,
                              Eigen::MatrixXd* jacobian = nullptr);

// The normal equations of one submap factor: h = J^T info J and g = J^T info e, for J the
// Jacobian PredictSubmap gives (over [X_k, X_k+1, L_1, ...]), info the submap's information
// matrix (its covariance's inverse) and e its residual. J is sparse: the end-pose rows depend
// on the two frames only, and the rows of landmark i on X_k and L_i only (one 2 x 2 block).
// So this costs O(n^2) for n rows, where the dense product costs O(n^3).
void SubmapNormalEquations(const Eigen::MatrixXd& j, const Eigen::MatrixXd& info, const Eigen::VectorXd& e,
                           Eigen::MatrixXd* h, Eigen::VectorXd* g);

struct JoinerOptions {
  int window = 8;           // agent.join_window: submaps relinearised; older ones are marginalised
  int max_iterations = 20;  // Gauss-Newton iterations per solve
  double tolerance = 1e-8;  // stop when no state entry moves more than this (m or rad), or the cost falls by
                            // less than this share
  // agent.join_relinearise_m: when a variable of the marginalised prior (a landmark, or the
  // oldest frame in the window) has moved this far (m or rad) from where the prior was
  // linearised, every submap is relinearised once and the prior rebuilt from them at the new
  // estimate (as iSAM2's fluid relinearisation, here whole); at most once per window of
  // submaps. 0: never (the submaps that left the window are then not kept).
  double relinearise_m = 0.0;
};

// The joined estimate: every landmark's mean and the landmarks' joint covariance, and the pose
// of the newest frame (the origin of the submap after the last one joined).
struct JoinedMap {
  std::vector<std::uint32_t> keys;  // increasing
  std::vector<Eigen::Vector2d> means;
  Eigen::MatrixXd cov;  // 2n x 2n, in keys' order
  Pose2 end;            // the end pose of the last submap joined
  Eigen::Matrix3d end_cov = Eigen::Matrix3d::Zero();
  Eigen::MatrixXd end_cross;  // 3 x 2n: covariance of the end pose with the landmarks
  int iterations = 0;         // Gauss-Newton iterations this solve took
  bool converged = true;

  Eigen::Matrix2d Cov(std::size_t i) const { return cov.block<2, 2>(2 * i, 2 * i); }
  Eigen::Matrix2d CrossCov(std::size_t i, std::size_t j) const { return cov.block<2, 2>(2 * i, 2 * j); }
  // The index of a key in keys, if present.
  std::optional<std::size_t> Find(std::uint32_t key) const;
};

class SubmapJoiner {
 public:
  explicit SubmapJoiner(const JoinerOptions& options = {});

  // Joins the next submap (its frame's origin is the previous one's end pose, or the joined
  // frame's origin for the first), solves, and marginalises what left the window. Throws
  // std::invalid_argument for a malformed submap (sizes, non-finite values, repeated keys, a
  // covariance that is not symmetric positive definite).
  void Add(const SubmapEstimate& submap);

  // The joined estimate, with `open` (the submap still being mapped) joined too if given;
  // the joiner itself is unchanged.
  JoinedMap Solve(const SubmapEstimate* open = nullptr) const;

  // The latest solution's estimates: the newest frame's origin and a landmark's mean.
  // The solution after the last Add (landmarks and the newest frame, with covariances).
  const JoinedMap& last() const { return last_; }
  std::size_t submaps() const { return submaps_; }
  std::size_t landmarks() const { return state_.landmarks.size(); }
  // Frames in the state (at most window + 1; X_0 is fixed and not one), and the prior's size.
  std::size_t window_frames() const { return state_.poses.size(); }
  std::size_t prior_dim() const { return static_cast<std::size_t>(prior_.h.rows()); }
  // Times every submap was relinearised (JoinerOptions::relinearise_m).
  int relinearisations() const { return relinearisations_; }

 private:
  struct Factor {
    std::size_t frame;  // the submap's index k: it joins X_k and X_{k+1}
    Eigen::VectorXd z;
    Eigen::MatrixXd sqrt_info;  // lower triangular L^-1, with p = L L^T
    std::vector<std::uint32_t> keys;
  };
  // A variable of the linear systems: a landmark by its key, or a frame by PoseVar(index).
  using Var = std::uint64_t;
  static constexpr Var kPoseBit = Var{1} << 63;
  static Var PoseVar(std::size_t frame) { return kPoseBit | frame; }
  // The marginalised submaps: cost 1/2 d' H d - g' d with d = x - x0 over vars.
  struct Prior {
    std::vector<Var> vars;
    Eigen::VectorXd x0;
    Eigen::MatrixXd h;
    Eigen::VectorXd g;
  };
  struct State {
    std::unordered_map<std::size_t, Pose2> poses;  // frames in the window (X_0 is fixed)
    std::unordered_map<std::uint32_t, Eigen::Vector2d> landmarks;
  };

  // A factor linearised at a state: the whitened Jacobian over its variables and the residual.
  struct Linearised {
    std::vector<std::pair<Var, int>> vars;  // (variable, size), in the Jacobian's column order
    Eigen::MatrixXd a;                      // sqrt_info * dh/dx
    Eigen::VectorXd r;                      // sqrt_info * (z - h)
  };

  static Factor MakeFactor(const SubmapEstimate& s, std::size_t frame);
  // Linearises f at the state (X_0 is fixed: a factor of frame 0 has no columns for it).
  static Linearised Linearise(const Factor& f, const State& state);
  // The state's value of a variable.
  static Eigen::VectorXd ValueOf(const State& state, Var var);
  // x - x0 over the prior's variables at the state, angles wrapped.
  Eigen::VectorXd PriorOffset(const State& state) const;
  // Initial values of what a new factor brings (its end frame, landmarks not seen before).
  static void Initialise(const Factor& f, State* state);
  // Gauss-Newton on state over factors and the prior; then the solution with covariances.
  JoinedMap Optimise(const std::deque<Factor>& factors, State* state) const;
  void Marginalise();
  // The largest move (m or rad) of a prior variable from the prior's linearisation point.
  double PriorDrift() const;
  // Every submap relinearised: one solve over all of them from the current estimate (frames
  // that left the window from where they left), with no prior; Add then marginalises again.
  void Relinearise();

  JoinerOptions options_;
  std::deque<Factor> factors_;  // in the window
  State state_;
  Prior prior_;
  std::size_t submaps_ = 0;
  // With relinearise_m: every factor, and each marginalised frame's value when it left.
  std::vector<Factor> history_;
  std::unordered_map<std::size_t, Pose2> left_frames_;
  int relinearisations_ = 0;
  std::size_t last_relinearised_ = 0;  // submaps_ at the last relinearisation
  JoinedMap last_;
};

}  // namespace mapmesh
