#include "common/slam/batch_slam.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <utility>

#include "common/check.h"
#include "common/geometry/rigid_fit.h"
#include "common/slam/motion_model.h"
#include "common/slam/observation_model.h"

namespace mapmesh {

std::size_t BatchRobotLog::Observations() const {
  std::size_t n = 0;
  for (const BatchNode& node : nodes) n += node.obs.size();
  return n;
}

BatchLogBuilder::BatchLogBuilder(RobotId robot, const FilterNoise& noise, double min_range_m, double max_range_m,
                                 std::optional<Pose2> start)
    : noise_(noise), min_range_m_(min_range_m), max_range_m_(max_range_m) {
  log_.robot = robot;
  log_.obs_cov = noise.obs_cov;
  log_.start = start;
  BatchNode first;
  first.stamp = std::numeric_limits<double>::quiet_NaN();
  log_.nodes.push_back(first);
}

void BatchLogBuilder::Move(const OdometryControl& u, double dt) {
  if (!(dt > 0)) return;
  Eigen::Matrix3d j_pose;
  // The models are invariant to the frame they start in, so integrating from the identity
  // gives the motion in the last node's frame, and the covariance propagates as the filter's.
  const Eigen::Matrix3d q = noise_.MotionCov(delta_, u, dt);
  delta_ = MoveRobot(noise_.motion, delta_, u, dt, &j_pose);
  delta_cov_ = j_pose * delta_cov_ * j_pose.transpose() + q;
  moved_ = true;
}

void BatchLogBuilder::Scan(double stamp, const std::vector<Observation>& obs) {
  std::vector<BatchObservation> kept;
  for (const Observation& o : obs) {
    if (o.kind != ObservationKind::kLandmark) continue;
    if (o.signature < 0 || !std::isfinite(o.range) || !std::isfinite(o.bearing) || o.range < min_range_m_ ||
        o.range > max_range_m_) {
      ++log_.observations_dropped;
      continue;
    }
    kept.push_back({o.signature, {o.range, o.bearing}});
  }
  if (kept.empty()) return;
  if (!moved_) {  // no odometry since the last node: the same pose
    BatchNode& last = log_.nodes.back();
    if (std::isnan(last.stamp)) last.stamp = stamp;
    last.obs.insert(last.obs.end(), kept.begin(), kept.end());
    return;
  }
  BatchNode node;
  node.stamp = stamp;
  node.delta = delta_;
  node.delta_cov = 0.5 * (delta_cov_ + delta_cov_.transpose());
  node.obs = std::move(kept);
  log_.nodes.push_back(std::move(node));
  delta_ = Pose2{};
  delta_cov_.setZero();
  moved_ = false;
}

int BatchLogBuilder::Mark(double stamp) {
  if (!moved_) {  // no odometry since the last node: the same pose
    BatchNode& last = log_.nodes.back();
    if (std::isnan(last.stamp)) last.stamp = stamp;
    return static_cast<int>(log_.nodes.size()) - 1;
  }
  BatchNode node;
  node.stamp = stamp;
  node.delta = delta_;
  node.delta_cov = 0.5 * (delta_cov_ + delta_cov_.transpose());
  log_.nodes.push_back(std::move(node));
  delta_ = Pose2{};
  delta_cov_.setZero();
  moved_ = false;
  return static_cast<int>(log_.nodes.size()) - 1;
}

Eigen::Vector3d RelativePoseError(const Pose2& a, const Pose2& b, const Pose2& delta, Eigen::Matrix3d* j_a,
                                  Eigen::Matrix3d* j_b) {
  const Pose2 d = Between(a, b, j_a, j_b);
  return {d.x - delta.x, d.y - delta.y, WrapAngle(d.theta - delta.theta)};
}

Eigen::Vector2d RangeBearingError(const Pose2& pose, const Eigen::Vector2d& m, const Eigen::Vector2d& z,
                                  Eigen::Matrix<double, 2, 3>* j_pose, Eigen::Matrix2d* j_m) {
  const Eigen::Vector2d h = ObserveRangeBearing(pose, m, j_pose, j_m);
  return {h(0) - z(0), WrapAngle(h(1) - z(1))};
}

Eigen::Vector2d SightingError(const Pose2& a, const Pose2& b, const Eigen::Vector2d& z,
                              Eigen::Matrix<double, 2, 3>* j_a, Eigen::Matrix<double, 2, 3>* j_b) {
  Eigen::Matrix2d j_m;
  const Eigen::Vector2d e = RangeBearingError(a, {b.x, b.y}, z, j_a, j_b ? &j_m : nullptr);
  if (j_b) *j_b << j_m, Eigen::Vector2d::Zero();
  return e;
}

namespace {

// The whitening of a covariance: S with S^T S = cov^-1 (S = L^-1 for cov = L L^T).
template <int N>
Eigen::Matrix<double, N, N> Whitening(const Eigen::Matrix<double, N, N>& cov) {
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(cov);
  MAPMESH_CHECK(llt.info() == Eigen::Success, "a factor's covariance is positive definite");
  return llt.matrixL().solve(Eigen::Matrix<double, N, N>::Identity());
}

// One robot's chain in a problem: its first `active` nodes, their current poses, and which are
// fixed or left out.
struct Chain {
  const BatchRobotLog* log = nullptr;
  int active = 0;
  std::vector<Pose2> poses;   // per node (at least `active`)
  std::vector<char> fixed;    // per node: not a variable
  std::vector<char> skipped;  // per node: no factor uses it (known-pose map: no truth there)
};

// A sighting between two chains of a problem (by index), at active, unskipped nodes.
struct ChainSighting {
  int a = 0, node_a = 0, b = 0, node_b = 0;
  Eigen::Vector2d z = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();
};

// The batch problem over some chains' active nodes, the landmarks they observe and the
// sightings between them.
class BatchProblem : public LeastSquaresProblem {
 public:
  // Landmarks not in `landmarks` start where their first observation puts them.
  BatchProblem(std::vector<Chain> chains, std::map<std::int32_t, Eigen::Vector2d> landmarks,
               const BatchOptions& options, const std::vector<ChainSighting>& sightings = {})
      : chains_(std::move(chains)), options_(options) {
    std::vector<int> sizes;
    for (Chain& c : chains_) {
      var_.emplace_back(static_cast<std::size_t>(c.active), -1);
      for (int i = 0; i < c.active; ++i) {
        if (!c.fixed[static_cast<std::size_t>(i)] && !c.skipped[static_cast<std::size_t>(i)]) {
          var_.back()[static_cast<std::size_t>(i)] = static_cast<int>(sizes.size());
          sizes.push_back(3);
        }
      }
    }
    for (std::size_t r = 0; r < chains_.size(); ++r) {
      const Chain& c = chains_[r];
      for (int i = 0; i < c.active; ++i) {
        if (c.skipped[static_cast<std::size_t>(i)]) continue;
        for (const BatchObservation& o : c.log->nodes[static_cast<std::size_t>(i)].obs) {
          if (landmark_index_.count(o.landmark)) continue;
          landmark_index_[o.landmark] = static_cast<int>(signatures_.size());
          signatures_.push_back(o.landmark);
          const auto known = landmarks.find(o.landmark);
          landmarks_.push_back(known != landmarks.end()
                                   ? known->second
                                   : InverseRangeBearing(c.poses[static_cast<std::size_t>(i)], o.z));
          landmark_var_.push_back(static_cast<int>(sizes.size()));
          sizes.push_back(2);
        }
      }
    }
    eq_ = std::make_unique<BlockNormalEquations>(sizes);
    for (std::size_t r = 0; r < chains_.size(); ++r) {
      const Chain& c = chains_[r];
      const Eigen::Matrix2d obs_white = Whitening<2>(c.log->obs_cov);
      for (int i = 0; i < c.active; ++i) {
        const std::size_t ui = static_cast<std::size_t>(i);
        if (c.skipped[ui]) continue;
        const BatchNode& node = c.log->nodes[ui];
        if (i > 0 && !c.skipped[ui - 1] && (var_[r][ui - 1] >= 0 || var_[r][ui] >= 0)) {
          Odo f;
          f.robot = static_cast<int>(r);
          f.node = i;
          f.delta = node.delta;
          f.white = Whitening<3>(node.delta_cov + options_.min_delta_variance * Eigen::Matrix3d::Identity());
          std::vector<int> vars;
          if (var_[r][ui - 1] >= 0) vars.push_back(var_[r][ui - 1]);
          if (var_[r][ui] >= 0) vars.push_back(var_[r][ui]);
          f.handle = eq_->Couple(vars);
          odo_.push_back(f);
        }
        for (const BatchObservation& o : node.obs) {
          Obs f;
          f.robot = static_cast<int>(r);
          f.node = i;
          f.landmark = landmark_index_.at(o.landmark);
          f.z = o.z;
          f.white = obs_white;
          std::vector<int> vars;
          if (var_[r][ui] >= 0) vars.push_back(var_[r][ui]);
          vars.push_back(landmark_var_[static_cast<std::size_t>(f.landmark)]);
          f.handle = eq_->Couple(vars);
          obs_.push_back(f);
        }
      }
    }
    for (const ChainSighting& s : sightings) {
      const std::size_t a = static_cast<std::size_t>(s.a), b = static_cast<std::size_t>(s.b);
      MAPMESH_CHECK(s.a != s.b && s.node_a < chains_[a].active && s.node_b < chains_[b].active &&
                        !chains_[a].skipped[static_cast<std::size_t>(s.node_a)] &&
                        !chains_[b].skipped[static_cast<std::size_t>(s.node_b)],
                    "a sighting joins two chains' active nodes");
      Sight f;
      f.a = s.a;
      f.node_a = s.node_a;
      f.b = s.b;
      f.node_b = s.node_b;
      f.z = s.z;
      f.white = Whitening<2>(s.cov);
      const int va = var_[a][static_cast<std::size_t>(s.node_a)], vb = var_[b][static_cast<std::size_t>(s.node_b)];
      if (va < 0 && vb < 0) continue;  // both fixed: nothing to estimate
      std::vector<int> vars;
      if (va >= 0) vars.push_back(va);
      if (vb >= 0) vars.push_back(vb);
      f.handle = eq_->Couple(vars);
      sight_.push_back(f);
    }
    eq_->Finalize();
  }

  BlockNormalEquations& equations() { return *eq_; }

  double Linearise(BlockNormalEquations& eq) override { return Evaluate(&eq); }
  double Cost() const override { return Evaluate(nullptr); }

  void Step(const Eigen::VectorXd& dx) override {
    for (std::size_t r = 0; r < chains_.size(); ++r) {
      for (std::size_t i = 0; i < var_[r].size(); ++i) {
        const int v = var_[r][i];
        if (v < 0) continue;
        const int o = eq_->offset(v);
        Pose2& p = chains_[r].poses[i];
        p = p.Retract(dx.segment<3>(o));
      }
    }
    for (std::size_t k = 0; k < landmarks_.size(); ++k) landmarks_[k] += dx.segment<2>(eq_->offset(landmark_var_[k]));
  }
  void Save() override {
    saved_poses_.clear();
    for (const Chain& c : chains_) saved_poses_.push_back(c.poses);
    saved_landmarks_ = landmarks_;
  }
  void Restore() override {
    for (std::size_t r = 0; r < chains_.size(); ++r) chains_[r].poses = saved_poses_[r];
    landmarks_ = saved_landmarks_;
  }

  // The solution: landmarks with their marginal covariances, and the chains' active nodes.
  void Extract(BatchSolution* out) {
    std::vector<int> vars(landmark_var_.begin(), landmark_var_.end());
    const std::vector<Eigen::MatrixXd> cov = vars.empty() ? std::vector<Eigen::MatrixXd>{} : eq_->Marginals(vars);
    out->covariance_ok = cov.size() == vars.size();
    out->map.landmarks.clear();
    // By increasing identity.
    std::vector<std::size_t> order(signatures_.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return signatures_[a] < signatures_[b]; });
    for (std::size_t k : order) {
      Landmark l;
      l.id = static_cast<std::uint32_t>(signatures_[k]);
      l.signature = signatures_[k];
      l.mean = landmarks_[k];
      l.cov = out->covariance_ok ? Eigen::Matrix2d(cov[k]) : Eigen::Matrix2d::Identity();
      out->map.landmarks.push_back(l);
    }
    out->trajectories.clear();
    for (std::size_t r = 0; r < chains_.size(); ++r) {
      auto& track = out->trajectories[chains_[r].log->robot];
      for (int i = 0; i < chains_[r].active; ++i) {
        if (chains_[r].skipped[static_cast<std::size_t>(i)]) continue;
        track.push_back({chains_[r].log->nodes[static_cast<std::size_t>(i)].stamp,
                         chains_[r].poses[static_cast<std::size_t>(i)]});
      }
    }
    out->variables = eq_->dim();
    out->observations = obs_.size();
    out->sightings = sight_.size();
    out->chi2_per_dof = Rows() > eq_->dim() ? chi2_ / static_cast<double>(Rows() - eq_->dim()) : 0.0;
  }

  // The joint covariance of chain 0's node `node` and every landmark (in signatures() order),
  // from the normal equations as last linearised; empty when not positive definite.
  Eigen::MatrixXd JointOfNodeAndLandmarks(int node) {
    std::vector<int> vars = {var_[0][static_cast<std::size_t>(node)]};
    vars.insert(vars.end(), landmark_var_.begin(), landmark_var_.end());
    return eq_->JointMarginal(vars);
  }
  const std::vector<std::int32_t>& signatures() const { return signatures_; }
  const std::vector<Eigen::Vector2d>& landmarks() const { return landmarks_; }

  // Residual rows, and the sum of the squared whitened residuals at the last evaluation.
  long Rows() const {
    return 3L * static_cast<long>(odo_.size()) + 2L * static_cast<long>(obs_.size() + sight_.size());
  }
  double chi2() const { return chi2_; }

  std::vector<Chain>& chains() { return chains_; }
  std::map<std::int32_t, Eigen::Vector2d> Landmarks() const {
    std::map<std::int32_t, Eigen::Vector2d> out;
    for (std::size_t k = 0; k < signatures_.size(); ++k) out[signatures_[k]] = landmarks_[k];
    return out;
  }

 private:
  struct Odo {
    int robot = 0, node = 0;  // joins node - 1 and node
    Pose2 delta;
    Eigen::Matrix3d white;
    int handle = 0;
  };
  struct Obs {
    int robot = 0, node = 0, landmark = 0;
    Eigen::Vector2d z;
    Eigen::Matrix2d white;
    int handle = 0;
  };
  struct Sight {
    int a = 0, node_a = 0, b = 0, node_b = 0;
    Eigen::Vector2d z;
    Eigen::Matrix2d white;
    int handle = 0;
  };

  // The cost 1/2 sum rho(|r|^2); with eq, also each factor's normal equations.
  double Evaluate(BlockNormalEquations* eq) const {
    double cost = 0.0;
    chi2_ = 0.0;
    Eigen::Matrix3d ja, jb;
    Eigen::Matrix<double, 3, 6> j6;
    for (const Odo& f : odo_) {
      const std::size_t r = static_cast<std::size_t>(f.robot), i = static_cast<std::size_t>(f.node);
      const std::vector<Pose2>& p = chains_[r].poses;
      const Eigen::Vector3d res = f.white *
                                  RelativePoseError(p[i - 1], p[i], f.delta, eq ? &ja : nullptr, eq ? &jb : nullptr);
      const double s = res.squaredNorm();
      cost += 0.5 * s;
      chi2_ += s;
      if (!eq) continue;
      int cols = 0;
      if (var_[r][i - 1] >= 0) j6.middleCols<3>(3 * cols++) = f.white * ja;
      if (var_[r][i] >= 0) j6.middleCols<3>(3 * cols++) = f.white * jb;
      eq->Add(f.handle, j6.leftCols(3 * cols), res);
    }
    Eigen::Matrix<double, 2, 3> jp;
    Eigen::Matrix2d jm;
    Eigen::Matrix<double, 2, 5> j5;
    for (const Obs& f : obs_) {
      const std::size_t r = static_cast<std::size_t>(f.robot), i = static_cast<std::size_t>(f.node);
      const Eigen::Vector2d res = f.white * RangeBearingError(chains_[r].poses[i],
                                                              landmarks_[static_cast<std::size_t>(f.landmark)], f.z,
                                                              eq ? &jp : nullptr, eq ? &jm : nullptr);
      const double s = res.squaredNorm();
      cost += 0.5 * options_.robust.Rho(s);
      chi2_ += s;
      if (!eq) continue;
      int cols = 0;
      if (var_[r][i] >= 0) {
        j5.leftCols<3>() = f.white * jp;
        cols = 3;
      }
      j5.middleCols<2>(cols) = f.white * jm;
      eq->Add(f.handle, j5.leftCols(cols + 2), res, options_.robust.Weight(s));
    }
    Eigen::Matrix<double, 2, 3> ja2, jb2;
    Eigen::Matrix<double, 2, 6> j6s;
    for (const Sight& f : sight_) {
      const std::size_t a = static_cast<std::size_t>(f.a), b = static_cast<std::size_t>(f.b);
      const std::size_t na = static_cast<std::size_t>(f.node_a), nb = static_cast<std::size_t>(f.node_b);
      const Eigen::Vector2d res = f.white * SightingError(chains_[a].poses[na], chains_[b].poses[nb], f.z,
                                                          eq ? &ja2 : nullptr, eq ? &jb2 : nullptr);
      const double s = res.squaredNorm();
      cost += 0.5 * options_.robust.Rho(s);
      chi2_ += s;
      if (!eq) continue;
      int cols = 0;
      if (var_[a][na] >= 0) j6s.middleCols<3>(3 * cols++) = f.white * ja2;
      if (var_[b][nb] >= 0) j6s.middleCols<3>(3 * cols++) = f.white * jb2;
      eq->Add(f.handle, j6s.leftCols(3 * cols), res, options_.robust.Weight(s));
    }
    return cost;
  }

  std::vector<Chain> chains_;
  BatchOptions options_;
  std::vector<std::vector<int>> var_;  // per chain and node: its variable, -1 when fixed or skipped
  std::map<std::int32_t, int> landmark_index_;
  std::vector<std::int32_t> signatures_;
  std::vector<Eigen::Vector2d> landmarks_;
  std::vector<int> landmark_var_;
  std::vector<Odo> odo_;
  std::vector<Obs> obs_;
  std::vector<Sight> sight_;
  std::unique_ptr<BlockNormalEquations> eq_;
  std::vector<std::vector<Pose2>> saved_poses_;
  std::vector<Eigen::Vector2d> saved_landmarks_;
  mutable double chi2_ = 0.0;  // the last evaluation's sum of squared whitened residuals
};

// A chain over all of a log's nodes, started by dead reckoning from `origin`, node 0 fixed.
Chain DeadReckoned(const BatchRobotLog& log, const Pose2& origin) {
  Chain c;
  c.log = &log;
  c.active = static_cast<int>(log.nodes.size());
  c.poses.resize(log.nodes.size());
  c.poses[0] = origin;
  for (std::size_t i = 1; i < log.nodes.size(); ++i) c.poses[i] = c.poses[i - 1] * log.nodes[i].delta;
  c.fixed.assign(log.nodes.size(), 0);
  c.fixed[0] = 1;
  c.skipped.assign(log.nodes.size(), 0);
  return c;
}

}  // namespace

BatchSolution SolveSingleRobotBatch(const BatchRobotLog& log, const BatchOptions& options) {
  MAPMESH_CHECK(!log.nodes.empty(), "a log has its start node");
  BatchSolution out;
  Chain chain = DeadReckoned(log, log.start.value_or(Pose2{}));
  std::map<std::int32_t, Eigen::Vector2d> landmarks;
  const int n = static_cast<int>(log.nodes.size());
  const int chunk = std::max(1, options.initial_chunk_nodes);
  // Growing prefixes: each solved, then the next chunk's nodes started from the last solved
  // node by odometry (a long chain's dead reckoning alone can be far from the optimum). While
  // the prefix grows, nodes well behind its end are held where they were solved, so that each
  // step costs what its window does; the whole chain is solved free at the end.
  const int window = options.initial_window_chunks > 0 ? options.initial_window_chunks * chunk : n;
  for (int active = std::min(n, chunk);; active = std::min(n, active + chunk)) {
    Chain c = chain;
    c.active = active;
    if (active < n) {
      for (int i = 0; i < active - window; ++i) c.fixed[static_cast<std::size_t>(i)] = 1;
    }
    BatchProblem problem({c}, landmarks, options);
    out.report = MinimiseLevenbergMarquardt(problem, problem.equations(), options.lm);
    ++out.solves;
    chain.poses = problem.chains()[0].poses;
    landmarks = problem.Landmarks();
    if (active == n) {
      problem.Extract(&out);
      break;
    }
    for (int i = active; i < n; ++i) {
      chain.poses[static_cast<std::size_t>(i)] = chain.poses[static_cast<std::size_t>(i - 1)] *
                                                 log.nodes[static_cast<std::size_t>(i)].delta;
    }
  }
  return out;
}

namespace {

// How a centralized solve is laid out: its components, each robot's place, the landmarks each
// component holds.
struct CentralPlan {
  struct Part {
    std::vector<std::size_t> robots;  // indices into the logs, in joining order
    std::vector<char> gauge;          // per robot of the part: its node 0 fixed
    std::vector<Pose2> frame;         // per robot of the part: its single solution's frame in the part's
    bool in_world = false;
    // The landmarks it holds (the sum and count of their placed estimates, for the start).
    std::map<std::int32_t, std::pair<Eigen::Vector2d, int>> landmarks;
  };
  std::vector<Part> parts;
  std::vector<int> part_of;           // per log
  std::map<std::int32_t, int> owner;  // landmark: the part that holds it
};

CentralPlan PlanCentral(const std::vector<BatchRobotLog>& logs, const std::vector<BatchSolution>& singles,
                        const std::vector<BatchSighting>& sightings, const std::map<RobotId, std::size_t>& index,
                        StartKnowledge starts) {
  const std::size_t n = logs.size();
  CentralPlan plan;
  plan.part_of.assign(n, -1);
  // Each robot's sightings (either side), those whose nodes its log holds.
  std::vector<std::vector<const BatchSighting*>> sights(n);
  for (const BatchSighting& s : sightings) {
    const auto a = index.find(s.robot), b = index.find(s.other);
    if (a == index.end() || b == index.end()) continue;
    if (s.node < 0 || static_cast<std::size_t>(s.node) >= logs[a->second].nodes.size() || s.other_node < 0 ||
        static_cast<std::size_t>(s.other_node) >= logs[b->second].nodes.size()) {
      continue;
    }
    sights[a->second].push_back(&s);
    sights[b->second].push_back(&s);
  }
  auto track = [&](std::size_t r) -> const std::vector<BatchPose>& {
    return singles[r].trajectories.at(logs[r].robot);
  };
  auto place = [&](std::size_t r, int k, const Pose2& frame, bool gauge) {
    CentralPlan::Part& part = plan.parts[static_cast<std::size_t>(k)];
    plan.part_of[r] = k;
    part.robots.push_back(r);
    part.gauge.push_back(gauge);
    part.frame.push_back(frame);
    for (const Landmark& l : singles[r].map.landmarks) {
      const auto owned = plan.owner.find(l.signature);
      if (owned != plan.owner.end() && owned->second != k) continue;
      auto& [sum, count] = part.landmarks.try_emplace(l.signature, Eigen::Vector2d::Zero(), 0).first->second;
      sum += frame.Apply(l.mean);
      ++count;
    }
  };
  // A robot's pose at a node where its part places it.
  auto placed_pose = [&](std::size_t r, int node) {
    const CentralPlan::Part& part = plan.parts[static_cast<std::size_t>(plan.part_of[r])];
    const std::size_t at = static_cast<std::size_t>(std::find(part.robots.begin(), part.robots.end(), r) -
                                                    part.robots.begin());
    return part.frame[at] * track(r)[static_cast<std::size_t>(node)].pose;
  };
  // Robot r's frame in part k from what it shares with it: landmarks the part holds and
  // sightings between r and the part's robots, as pairs of points (r's single frame, k's).
  auto fit = [&](std::size_t r, int k) -> std::optional<Pose2> {
    const CentralPlan::Part& part = plan.parts[static_cast<std::size_t>(k)];
    std::vector<Eigen::Vector2d> src, dst;
    for (const Landmark& l : singles[r].map.landmarks) {
      const auto it = part.landmarks.find(l.signature);
      if (it == part.landmarks.end()) continue;
      src.push_back(l.mean);
      dst.push_back(it->second.first / it->second.second);
    }
    for (const BatchSighting* s : sights[r]) {
      const bool sees = index.at(s->robot) == r;
      const std::size_t o = index.at(sees ? s->other : s->robot);
      if (plan.part_of[o] != k) continue;
      if (sees) {  // r saw o
        src.push_back(InverseRangeBearing(track(r)[static_cast<std::size_t>(s->node)].pose, s->z));
        const Pose2 at = placed_pose(o, s->other_node);
        dst.emplace_back(at.x, at.y);
      } else {  // o saw r
        const Pose2 at = track(r)[static_cast<std::size_t>(s->other_node)].pose;
        src.emplace_back(at.x, at.y);
        dst.push_back(InverseRangeBearing(placed_pose(o, s->node), s->z));
      }
    }
    if (src.size() < 2) return std::nullopt;
    return FitRigid2D(src, dst);
  };
  auto close = [&](int k) {
    for (const auto& [sig, _] : plan.parts[static_cast<std::size_t>(k)].landmarks) plan.owner.try_emplace(sig, k);
  };
  for (int k = 0;; ++k) {
    std::vector<std::size_t> seeds;
    if (k == 0 && starts == StartKnowledge::kKnown) {
      for (std::size_t r = 0; r < n; ++r) {
        if (logs[r].start) seeds.push_back(r);
      }
    }
    if (seeds.empty()) {
      for (std::size_t r = 0; r < n && seeds.empty(); ++r) {
        if (plan.part_of[r] < 0) seeds.push_back(r);
      }
    }
    if (seeds.empty()) break;
    plan.parts.emplace_back();
    plan.parts.back().in_world = std::all_of(seeds.begin(), seeds.end(), [&](std::size_t r) { return logs[r].start; });
    for (std::size_t r : seeds) place(r, k, Pose2{}, true);
    for (bool progress = true; progress;) {
      progress = false;
      for (std::size_t r = 0; r < n; ++r) {
        if (plan.part_of[r] >= 0) continue;
        if (const std::optional<Pose2> frame = fit(r, k)) {
          place(r, k, *frame, false);
          progress = true;
        }
      }
    }
    close(k);
  }
  return plan;
}

}  // namespace

BatchSolution SolveCentralBatch(const std::vector<BatchRobotLog>& logs, const std::vector<BatchSolution>& singles,
                                const std::vector<BatchSighting>& sightings, const CentralBatchOptions& options,
                                const CentralStart* from) {
  MAPMESH_CHECK(logs.size() == singles.size(), "one single-robot solution per log");
  BatchSolution out;
  if (logs.empty()) return out;
  std::map<RobotId, std::size_t> index;
  for (std::size_t r = 0; r < logs.size(); ++r) {
    MAPMESH_CHECK(index.emplace(logs[r].robot, r).second, "one log per robot");
    const auto& track = singles[r].trajectories.at(logs[r].robot);
    MAPMESH_CHECK(track.size() == logs[r].nodes.size(), "a single-robot solution covers its log");
  }
  const CentralPlan plan = PlanCentral(logs, singles, sightings, index, options.starts);
  out.report.converged = true;
  double chi2 = 0.0;
  long dof = 0;
  std::vector<std::pair<int, std::size_t>> order;  // (landmarks, part): the largest first
  std::vector<BatchSolution> solved;
  for (std::size_t k = 0; k < plan.parts.size(); ++k) {
    const CentralPlan::Part& part = plan.parts[k];
    // Each robot's log without the observations of landmarks an earlier part holds.
    std::vector<BatchRobotLog> kept;
    kept.reserve(part.robots.size());
    for (std::size_t r : part.robots) {
      kept.push_back(logs[r]);
      for (BatchNode& node : kept.back().nodes) {
        const auto end = std::remove_if(node.obs.begin(), node.obs.end(), [&](const BatchObservation& o) {
          return plan.owner.at(o.landmark) != static_cast<int>(k);
        });
        out.observations_left_out += static_cast<std::size_t>(node.obs.end() - end);
        node.obs.erase(end, node.obs.end());
      }
    }
    std::vector<Chain> chains;
    for (std::size_t i = 0; i < part.robots.size(); ++i) {
      const std::size_t r = part.robots[i];
      Chain c = DeadReckoned(kept[i], Pose2{});
      const auto& track = singles[r].trajectories.at(logs[r].robot);
      const std::vector<Pose2>* given = nullptr;
      if (from) {
        const auto it = from->poses.find(logs[r].robot);
        if (it != from->poses.end() && it->second.size() == track.size()) given = &it->second;
      }
      for (std::size_t j = 0; j < track.size(); ++j) c.poses[j] = given ? (*given)[j] : part.frame[i] * track[j].pose;
      c.fixed[0] = part.gauge[i];
      if (part.gauge[i]) c.poses[0] = part.frame[i] * track[0].pose;  // where the gauge holds it
      chains.push_back(std::move(c));
    }
    std::map<std::int32_t, Eigen::Vector2d> landmarks;
    for (const auto& [sig, sum] : part.landmarks) landmarks[sig] = sum.first / sum.second;
    if (from) {
      for (auto& [sig, at] : landmarks) {
        if (const auto it = from->landmarks.find(sig); it != from->landmarks.end()) at = it->second;
      }
    }
    std::vector<ChainSighting> chain_sightings;
    for (const BatchSighting& s : sightings) {
      const auto a = index.find(s.robot), b = index.find(s.other);
      if (a == index.end() || b == index.end()) continue;
      const int pa = plan.part_of[a->second], pb = plan.part_of[b->second];
      if (pa != static_cast<int>(k) && pb != static_cast<int>(k)) continue;
      const bool nodes_held = s.node >= 0 && static_cast<std::size_t>(s.node) < logs[a->second].nodes.size() &&
                              s.other_node >= 0 &&
                              static_cast<std::size_t>(s.other_node) < logs[b->second].nodes.size();
      if (pa != pb || !nodes_held) {
        if (pa == static_cast<int>(k)) ++out.sightings_left_out;  // counted once
        continue;
      }
      auto chain = [&](std::size_t r) {
        return static_cast<int>(std::find(part.robots.begin(), part.robots.end(), r) - part.robots.begin());
      };
      chain_sightings.push_back({chain(a->second), s.node, chain(b->second), s.other_node, s.z, s.cov});
    }
    BatchSolution part_out;
    BatchProblem problem(std::move(chains), landmarks, options.batch, chain_sightings);
    if (problem.equations().dim() > 0) {
      part_out.report = MinimiseLevenbergMarquardt(problem, problem.equations(), options.batch.lm);
      ++out.solves;
    } else {
      part_out.report.converged = true;
      part_out.report.stop = "cost";
      problem.Cost();
    }
    problem.Extract(&part_out);
    chi2 += problem.chi2();
    dof += std::max(0L, problem.Rows() - problem.equations().dim());
    order.emplace_back(static_cast<int>(part_out.map.size()), k);
    solved.push_back(std::move(part_out));
  }
  // The largest component first (by landmarks), ties in planning order.
  std::stable_sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  for (const auto& [count, k] : order) {
    const int c = static_cast<int>(out.components.size());
    BatchComponent comp;
    for (std::size_t r : plan.parts[k].robots) comp.robots.push_back(logs[r].robot);
    comp.in_world = plan.parts[k].in_world;
    comp.landmarks = count;
    out.components.push_back(std::move(comp));
    BatchSolution& s = solved[k];
    for (const Landmark& l : s.map.landmarks) {
      out.map.landmarks.push_back(l);
      out.landmark_component[l.signature] = c;
    }
    for (auto& [robot, t] : s.trajectories) out.trajectories[robot] = std::move(t);
    out.report.iterations += s.report.iterations;
    out.report.steps_accepted += s.report.steps_accepted;
    out.report.initial_cost += s.report.initial_cost;
    out.report.final_cost += s.report.final_cost;
    if (out.report.stop.empty() || (out.report.converged && !s.report.converged)) out.report.stop = s.report.stop;
    out.report.converged = out.report.converged && s.report.converged;
    out.variables += s.variables;
    out.observations += s.observations;
    out.sightings += s.sightings;
    out.covariance_ok = out.covariance_ok && s.covariance_ok;
  }
  std::sort(out.map.landmarks.begin(), out.map.landmarks.end(),
            [](const Landmark& a, const Landmark& b) { return a.signature < b.signature; });
  out.chi2_per_dof = dof > 0 ? chi2 / static_cast<double>(dof) : 0.0;
  return out;
}

std::optional<WireSubmap> SolveBatchWindow(const BatchRobotLog& log, int first, int last, bool with_last,
                                           const BatchOptions& options) {
  MAPMESH_CHECK(0 <= first && first < last && static_cast<std::size_t>(last) < log.nodes.size(),
                "a window of the log's nodes");
  BatchRobotLog window;
  window.robot = log.robot;
  window.obs_cov = log.obs_cov;
  window.nodes.assign(log.nodes.begin() + first, log.nodes.begin() + last + 1);
  if (!with_last) window.nodes.back().obs.clear();
  BatchProblem problem({DeadReckoned(window, Pose2{})}, {}, options);
  MinimiseLevenbergMarquardt(problem, problem.equations(), options.lm);
  const int end = last - first;
  const Eigen::MatrixXd cov = problem.JointOfNodeAndLandmarks(end);
  if (cov.size() == 0) return std::nullopt;
  WireSubmap out;
  out.opened_s = std::isnan(window.nodes.front().stamp) ? 0.0 : window.nodes.front().stamp;
  out.closed_s = window.nodes.back().stamp;
  const std::size_t n = problem.signatures().size();
  out.x.resize(3 + 2 * static_cast<Eigen::Index>(n));
  const Pose2& at = problem.chains()[0].poses[static_cast<std::size_t>(end)];
  out.x.head<3>() << at.x, at.y, at.theta;
  for (std::size_t k = 0; k < n; ++k) {
    out.keys.push_back(static_cast<std::uint32_t>(problem.signatures()[k]));
    out.x.segment<2>(3 + 2 * static_cast<Eigen::Index>(k)) = problem.landmarks()[k];
  }
  if (!out.SetCovariance(0.5 * (cov + cov.transpose()))) return std::nullopt;
  return out;
}

BatchSolution SolveKnownPoseMap(const std::vector<BatchRobotLog>& logs, const BatchTruePose& true_pose,
                                const BatchOptions& options) {
  BatchSolution out;
  std::vector<Chain> chains;
  for (const BatchRobotLog& log : logs) {
    Chain c = DeadReckoned(log, Pose2{});
    for (std::size_t i = 0; i < log.nodes.size(); ++i) {
      c.fixed[i] = 1;
      const std::optional<Pose2> truth = log.nodes[i].obs.empty() ? std::nullopt
                                                                  : true_pose(log.robot, log.nodes[i].stamp);
      c.skipped[i] = !truth;
      if (truth) c.poses[i] = *truth;
    }
    chains.push_back(std::move(c));
  }
  BatchProblem problem(std::move(chains), {}, options);
  out.report = MinimiseLevenbergMarquardt(problem, problem.equations(), options.lm);
  out.solves = 1;
  problem.Extract(&out);
  return out;
}

}  // namespace mapmesh
