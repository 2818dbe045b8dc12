#pragma once
// The batch optimum of landmark SLAM over one robot's data or many robots' at once: what the
// data allows when every measurement is used at once, the limit an online, decentralized map
// is judged against (docs/EXPERIMENTS.md "The limit").
//
// Each robot's poses are taken at its scans (nodes). The odometry between two nodes is
// integrated, with the filter's own motion model and noise (FilterNoise), into one relative-pose
// factor with its propagated covariance: exact whatever the odometry's rate, since the
// unicycle and car models are invariant to the frame they start in. Each landmark observation
// is a range-bearing factor, with known association (the signature). Robots' sightings of
// each other (a range and bearing of the other robot's position) are factors too, between the
// two robots' nodes at the sighting's time.
//
// What the centralized solve knows of where the robots started is a choice (CentralBatchOptions):
// - none, as no agent does (the fair optimum, docs/EXPERIMENTS.md "The limit"): the robots form
//   components, each robot joining one when it shares at least two links with it (a landmark
//   both observe, or a sighting between them: fewer leave its frame free to turn). Each
//   component's first robot is its gauge, node 0 fixed at its true start where known, else at
//   the origin; every other robot's start is free. A component is solved apart from the others
//   (a landmark two components observe stays with the first; a sighting across components is
//   left out), since nothing in the data ties their frames.
// - every robot's true start where known (an oracle), each of those node 0s fixed; robots of
//   unknown start are placed from shared landmarks and sightings, as above.
// The problem is solved by Levenberg-Marquardt over a sparse Cholesky factorisation
// (common/solver/least_squares.h), with a robust loss on the observations for real data, and
// the landmarks' marginal covariances come from the information matrix at the optimum.
//
// The same problem with every node fixed at its true pose is the known-pose map: each landmark
// from all its observations, what the sensor alone allows.
//
// Pure: Eigen only, no clocks, threads or random numbers.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/map/submap_codec.h"
#include "common/slam/landmark_filter.h"
#include "common/solver/least_squares.h"
#include "common/types/messages.h"

namespace mapmesh {

// One observation of a batch problem: the landmark's identity and z = [range, bearing].
struct BatchObservation {
  std::int32_t landmark = -1;
  Eigen::Vector2d z = Eigen::Vector2d::Zero();
};

// A node of a robot's chain: its pose at a scan. Odometry since the previous node is in
// `delta` (this node's pose in the previous node's frame) with covariance `delta_cov`.
struct BatchNode {
  double stamp = 0.0;  // s; node 0's is its first scan's, NaN when it has none
  Pose2 delta;
  Eigen::Matrix3d delta_cov = Eigen::Matrix3d::Zero();
  std::vector<BatchObservation> obs;
};

// One robot's data: node 0 is where its odometry starts, each later node a scan with landmark
// observations.
struct BatchRobotLog {
  RobotId robot = 0;
  Eigen::Matrix2d obs_cov = Eigen::Matrix2d::Identity();  // of [range, bearing]
  std::optional<Pose2> start;                             // the true pose at node 0, when known
  std::vector<BatchNode> nodes;
  int observations_dropped = 0;  // without a landmark identity, or outside the range limits
  std::size_t Observations() const;
};

// A robot's sighting of another: z = [range, bearing] of robot `other`'s position at node
// `other_node` of its log, from robot `robot`'s node `node` (both nodes at the sighting's time).
struct BatchSighting {
  RobotId robot = 0;
  int node = 0;
  RobotId other = 0;
  int other_node = 0;
  double stamp = 0.0;
  Eigen::Vector2d z = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();  // of [range, bearing]
};

// Builds a robot's log from its data in time order, as its agent's estimator receives it:
// odometry (Move) integrated from the previous node, landmark observations (Scan) kept when
// they carry an identity and a range within [min_range_m, max_range_m].
class BatchLogBuilder {
 public:
  BatchLogBuilder(RobotId robot, const FilterNoise& noise, double min_range_m, double max_range_m,
                  std::optional<Pose2> start);
  void Move(const OdometryControl& u, double dt);
  void Scan(double stamp, const std::vector<Observation>& obs);
  // A node at the robot's pose now (a sighting's end): the last node when the robot has not
  // moved since it, else a new node without observations. Returns its index.
  int Mark(double stamp);
  const BatchRobotLog& log() const { return log_; }

 private:
  FilterNoise noise_;
  double min_range_m_, max_range_m_;
  BatchRobotLog log_;
  Pose2 delta_;
  Eigen::Matrix3d delta_cov_ = Eigen::Matrix3d::Zero();
  bool moved_ = false;  // odometry since the last node
};

// The relative-pose factor's error: Between(a, b) - delta, the heading wrapped, with its
// Jacobians with respect to a and b.
Eigen::Vector3d RelativePoseError(const Pose2& a, const Pose2& b, const Pose2& delta, Eigen::Matrix3d* j_a = nullptr,
                                  Eigen::Matrix3d* j_b = nullptr);

// The range-bearing factor's error: the predicted [range, bearing] of landmark m from pose
// minus z, the bearing wrapped, with its Jacobians with respect to the pose and the landmark.
Eigen::Vector2d RangeBearingError(const Pose2& pose, const Eigen::Vector2d& m, const Eigen::Vector2d& z,
                                  Eigen::Matrix<double, 2, 3>* j_pose = nullptr, Eigen::Matrix2d* j_m = nullptr);

struct BatchOptions {
  RobustKernel robust;            // on each observation's whitened residual (odometry stays Gaussian)
  LevenbergMarquardtOptions lm;   // each solve
  int initial_chunk_nodes = 100;  // a robot's chain is first solved over growing prefixes of this many nodes
                                  // each, every new node started from the last solved one by odometry ...
  int initial_window_chunks = 2;  // ... with the nodes more than this many chunks back held where they were
                                  // solved (0: none held), then once over all nodes
  // Added to each odometry factor's covariance diagonal (m^2, rad^2): one short interval's
  // covariance has rank 2 (no sideways slip in the model). 1e-8 (0.1 mm, 0.006 deg) is far below
  // any odometry's noise and keeps a few-millisecond interval's factor (a node at a sighting's
  // time) within what the solver converges on: at 1e-10 MRCLAM 7's central solve with its
  // sightings stopped unconverged after 100 steps (cost 3261 against 3167 from the truth).
  double min_delta_variance = 1e-8;
};

// The sighting factor's error: the predicted [range, bearing] of the other robot's position
// from pose a minus z, with its Jacobians with respect to a and b (b's heading does not enter).
Eigen::Vector2d SightingError(const Pose2& a, const Pose2& b, const Eigen::Vector2d& z,
                              Eigen::Matrix<double, 2, 3>* j_a = nullptr, Eigen::Matrix<double, 2, 3>* j_b = nullptr);

// What the centralized solve knows of the robots' starts (see the top of this file).
enum class StartKnowledge {
  kNone,   // the agents' knowledge: each component's gauge only
  kKnown,  // every robot's true start where known, as an oracle
};

struct CentralBatchOptions {
  BatchOptions batch;
  StartKnowledge starts = StartKnowledge::kNone;
};

// Robots whose frames the data ties: solved together, apart from the others.
struct BatchComponent {
  std::vector<RobotId> robots;  // the gauge first, then in the order they joined
  // The gauge's node 0 is at its true start (so the component is in the world frame), else at
  // the origin. With known starts, every robot of known start is a gauge of the first component.
  bool in_world = false;
  int landmarks = 0;
};

// A pose of a solved chain.
struct BatchPose {
  double stamp = 0.0;
  Pose2 pose;
};

// What a batch solve found: landmarks by identity (the signature, also the id) with their
// marginal covariances, in the frame of the fixed start poses (the world, when the starts are
// true ones), and every robot's nodes.
struct BatchSolution {
  LandmarkMap map;
  std::map<RobotId, std::vector<BatchPose>> trajectories;
  LevenbergMarquardtReport report;  // of the last solve
  int solves = 0;                   // Levenberg-Marquardt runs, the growing prefixes included
  int variables = 0;                // of the last solve (scalars)
  std::size_t observations = 0;
  bool covariance_ok = true;  // the information matrix was positive definite at the optimum
  // The residuals at the optimum: sum of the squared whitened residuals over (rows - variables),
  // near 1 when the noise is what the model says.
  double chi2_per_dof = 0.0;
  std::size_t sightings = 0;  // sighting factors used
  // A centralized solve's components (the largest first, by landmarks): one unless some robots'
  // data share too little with the rest. Each landmark's component, by identity.
  std::vector<BatchComponent> components;
  std::map<std::int32_t, int> landmark_component;
  std::size_t observations_left_out = 0;  // of a landmark an earlier component holds
  std::size_t sightings_left_out = 0;     // across components
};

// The batch optimum of one robot's data: node 0 at the robot's true start, else at the origin.
BatchSolution SolveSingleRobotBatch(const BatchRobotLog& log, const BatchOptions& options = {});

// Where a centralized solve starts: every robot's nodes and the landmarks (missing ones start
// where their first observation puts them). A check: the truth, to see that the solve from the
// robots' own solutions reaches the same cost.
struct CentralStart {
  std::map<RobotId, std::vector<Pose2>> poses;  // per robot, one per node of its log
  std::map<std::int32_t, Eigen::Vector2d> landmarks;
};

// The centralized batch optimum of every robot's data (logs in increasing robot order) and
// their sightings, started from their single-robot solutions (`singles`, one per log in the same
// order, each in its start's frame): each robot not a gauge is placed by a rigid fit of its
// landmarks and sighted positions to those already placed (no truth used), or, with `from`,
// where it says (a gauge's node 0 stays where the gauge fixes it).
BatchSolution SolveCentralBatch(const std::vector<BatchRobotLog>& logs, const std::vector<BatchSolution>& singles,
                                const std::vector<BatchSighting>& sightings, const CentralBatchOptions& options,
                                const CentralStart* from = nullptr);

// The exact batch estimate of one window of a robot's log, nodes first .. last (first < last),
// as a submap (common/map/submap_codec.h) in the frame of node `first`: the robot's pose at node
// `last` and the landmarks observed at nodes first .. last - 1 (and at `last` too, with
// with_last), keyed by their identities, with their joint covariance (the marginal of the
// window's information at its optimum). Windows that share only their end nodes use every
// odometry interval and observation once: least-squares joining of such submaps
// (SubmapNetwork) is the batch optimum of the whole log, up to linearisation. The id is left
// for the caller; nullopt when the window's information is not positive definite.
std::optional<WireSubmap> SolveBatchWindow(const BatchRobotLog& log, int first, int last, bool with_last,
                                           const BatchOptions& options = {});

// The true pose of a robot at a time, nullopt when unknown.
using BatchTruePose = std::function<std::optional<Pose2>(RobotId robot, double stamp)>;

// The known-pose map: every observation taken from the robot's true pose at its stamp, the
// poses fixed; nodes whose true pose is unknown are left out.
BatchSolution SolveKnownPoseMap(const std::vector<BatchRobotLog>& logs, const BatchTruePose& true_pose,
                                const BatchOptions& options = {});

}  // namespace mapmesh
