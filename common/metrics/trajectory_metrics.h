#pragma once
// Trajectory error against a reference (ground truth or GPS), optionally after a
// least-squares rigid alignment when the estimate's frame is unknown.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/geometry/pose_track.h"
#include "common/types/messages.h"

namespace mapmesh {

struct TimedPosition {
  double t = 0.0;
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
};

struct TrajectoryError {
  int samples = 0;
  double rmse_m = 0.0;
  bool aligned = false;
  std::vector<double> times, errors_m;  // per compared reference fix
};

// Compares at every reference time inside the estimate's span where the estimate has samples
// at most max_gap_s apart around it (the estimate is interpolated linearly there). With
// align, the estimate is first moved by the rigid transform that best fits it to the
// reference (Umeyama); samples stays 0 if that fit is impossible.
TrajectoryError CompareTrajectory(const std::vector<TimedPosition>& estimate,
                                  const std::vector<TimedPosition>& reference, bool align, double max_gap_s = 1.0);

// Relative pose error (Sturm et al. 2012, as evo's `evo_rpe`): how well the estimate holds the
// motion over spans of delta_s, whatever its frame. For each reference pose Q_i and the first
// reference pose Q_j at least delta_s later (at most max_gap_s past delta_s), with the estimate
// P interpolated at both times (between samples at most max_gap_s apart; pairs it does not
// cover are skipped): E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j); the RMSE of |t(E)| and of |theta(E)|.
struct RelativeTrajectoryError {
  int pairs = 0;
  double translation_rmse_m = 0.0;
  double rotation_rmse_rad = 0.0;
};
RelativeTrajectoryError CompareRelativePoses(const std::vector<PoseStamp>& estimate,
                                             const std::vector<PoseStamp>& reference, double delta_s,
                                             double max_gap_s = 1.0);

// Drops reference fixes that imply a speed above max_speed_mps from the last kept fix
// (GPS glitches).
std::vector<TimedPosition> DropImplausibleFixes(const std::vector<TimedPosition>& fixes, double max_speed_mps);

}  // namespace mapmesh

namespace mapmesh {

struct Pose2;

// How far an estimated frame transform is from the true one: the distance between where
// the two put a reference point (for example the centroid of the mapped landmarks), and the
// rotation difference.
struct TransformError {
  double translation_m = 0.0;
  double rotation_rad = 0.0;
};
// The true pose at time t from stamped samples in time order, interpolated between them
// (clamped to the ends); nullopt when there are none.
std::optional<Pose2> TruthAt(const std::vector<GroundTruth>& track, double t);

TransformError CompareTransforms(const Pose2& estimate, const Pose2& truth, const Eigen::Vector2d& at);

}  // namespace mapmesh
