#pragma once
// A dense EKF over [robot pose (3), landmarks (2 each)]: the full EKF-SLAM of thesis 3.2.2,
// and the active part of the compressed filter. Storage grows geometrically, so adding a
// landmark does not copy the whole covariance.
//
// First-estimates Jacobians (FEJ-EKF; Huang, Mourikis & Roumeliotis, ISER 2008 and IJRR
// 2010): the standard EKF evaluates every Jacobian at the latest estimate, so its linearised
// model gains spurious information about the global heading, which no sensor observes, and
// the filter becomes overconfident on long runs. FEJ evaluates
// - the observation Jacobians at each landmark's first estimate (where it was initialised)
//   and at the robot's propagated position of that step (before any update at that time);
// - the propagation Jacobian with the position change counted from that propagated position,
//   d(p')/d(theta) = J (p' - p_propagated), J the 90 degree rotation;
// - the initialisation Jacobian of a new landmark likewise (its first estimate and the
//   robot's propagated position),
// so that global translation and rotation stay unobservable in the linearised filter. The
// innovations and the state propagation still use the latest estimates.

#include <Eigen/Core>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/slam/landmark_filter.h"
#include "common/slam/motion_model.h"
#include "common/slam/observation_model.h"

namespace mapmesh {

// Makes room for n entries in a state vector and its covariance, keeping the first `used`:
// storage grows geometrically (at least doubling), so the O(N^2) copy is rare. A vector
// alongside the state (first estimates) grows with it.
void GrowStateStorage(Eigen::VectorXd& x, Eigen::MatrixXd& p, int used, int n, Eigen::VectorXd* alongside = nullptr);

// How the filters (full and compressed EKF) linearise.
struct EkfOptions {
  bool first_estimates_jacobians = true;  // agent.first_estimates_jacobians: FEJ-EKF (see above), for consistency

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md).
  template <typename Reader>
  void Read(Reader& r) {
    r.Get("first_estimates_jacobians", first_estimates_jacobians);
  }
};

class EkfState {
 public:
  // The robot at the origin of its own frame, with zero covariance (it defines the frame).
  explicit EkfState(const EkfOptions& options = {});
  // A given state (x: 3 + 2k, P: square of the same size); its first estimates are x.
  EkfState(const Eigen::VectorXd& x, const Eigen::MatrixXd& p, const EkfOptions& options = {});
  // A given state with its first estimates (the size of x; see first_estimates()).
  EkfState(const Eigen::VectorXd& x, const Eigen::MatrixXd& p, const Eigen::VectorXd& first_estimates,
           const EkfOptions& options);

  int size() const { return n_; }
  int landmarks() const { return (n_ - 3) / 2; }
  Pose2 robot() const { return {x_(0), x_(1), x_(2)}; }
  Eigen::Vector2d landmark(int slot) const { return x_.segment<2>(3 + 2 * slot); }
  auto x() const { return x_.head(n_); }
  auto P() const { return P_.topLeftCorner(n_, n_); }
  // Alongside x: the robot's propagated pose of the current step (its pose before any update
  // since the last prediction), then each landmark's first estimate. Kept whether or not the
  // Jacobians use them (EkfOptions::first_estimates_jacobians).
  auto first_estimates() const { return fe_.head(n_); }
  Eigen::Vector2d first_estimate(int slot) const { return fe_.segment<2>(3 + 2 * slot); }

  // EKF prediction (thesis eq. 19-22): only the robot rows and columns of P change; the
  // landmark block is not touched. The pose gains the motion's covariance noise.MotionCov
  // (white control noise integrated along the motion). Returns the robot Jacobian of the
  // motion that was used.
  Eigen::Matrix3d Predict(const FilterNoise& noise, const OdometryControl& u, double dt);

  // One observation of a landmark slot.
  struct Measurement {
    int slot = 0;
    Eigen::Vector2d z = Eigen::Vector2d::Zero();  // range, bearing
  };
  // What the compressed filter needs from an update, all taken before it changes P:
  // beta = H^T S^-1 H, y = H^T S^-1 nu, mu = P beta.
  struct UpdateTerms {
    Eigen::MatrixXd beta, mu;
    Eigen::VectorXd y;
  };
  // Batch EKF update with every measurement of a scan at once (thesis eq. 23-25), in the
  // standard form followed by symmetrisation. False (and no change) if S is not positive
  // definite. The innovations use the latest estimates, the Jacobians those of Jacobians().
  bool Update(const std::vector<Measurement>& obs, const Eigen::Matrix2d& obs_cov, UpdateTerms* terms = nullptr);

  // Predicted observation of a slot and its Jacobians, both at the latest estimates.
  Eigen::Vector2d Predicted(int slot, Matrix23* h_robot, Eigen::Matrix2d* h_landmark) const;
  // The observation Jacobians of a slot that Update uses: at the latest estimates, or with
  // first-estimates Jacobians at the robot's propagated position and the landmark's first
  // estimate.
  void Jacobians(int slot, Matrix23* h_robot, Eigen::Matrix2d* h_landmark) const;

  // Initialises a landmark from z through the inverse observation model; its cross
  // covariances follow from the robot's rows. Returns the new slot; g_robot receives the
  // Jacobian of the initialisation with respect to the robot that was used.
  int Augment(const Eigen::Vector2d& z, const Eigen::Matrix2d& obs_cov, Matrix23* g_robot = nullptr);

 private:
  void Reserve(int n);

  EkfOptions options_;
  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  Eigen::VectorXd fe_;  // first estimates, alongside x_ (same storage size)
  int n_ = 3;
};

}  // namespace mapmesh
