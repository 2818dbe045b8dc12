#pragma once
// In-process SLAM experiments: a scenario's streams (simulated or replayed) go straight into
// each robot's local estimator, with no DDS, and the result is scored against the truth.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "common/map/landmark_map.h"

namespace mapmesh::lab {

struct SlamRunOptions {
  std::string datasets_root;     // for dataset scenarios
  bool hide_signatures = false;  // feed the estimator unidentified observations, score associations
};

// One robot's result in one run.
struct SlamRunResult {
  std::uint64_t seed = 0;
  RobotId robot = 0;
  int landmarks = 0;
  bool map_evaluated = false;
  bool map_aligned = false;  // scored after a rigid fit (start pose unknown)
  double landmark_rmse_m = 0.0;
  double landmark_rmse_aligned_m = 0.0;  // after a least-squares rigid fit to the truth, whatever the start
  double landmark_nees = 0.0;            // mean over landmarks (2 dof)
  double consistent_ratio = 0.0;
  double coverage = 0.0;
  double shape_sigma_m = 0.0;      // the map's shape precision (LandmarkMap::shape_sigma_m)
  double median_sigma_m = 0.0;     // median over landmarks of the marginal's largest standard deviation
  int pose_samples = 0;            // scans at which the pose was scored
  double pose_nees = 0.0;          // mean over scans (3 dof); needs true headings
  double trajectory_rmse_m = 0.0;  // position error at each scan (after a rigid fit when the start is unknown)
  bool trajectory_aligned = false;
  double trajectory_rmse_aligned_m = 0.0;  // the same after a rigid fit of the whole path to the truth
  long associations = 0;                   // hide_signatures: observations fused into a landmark
  long wrong_associations = 0;             // ... into a landmark started by another true landmark
  long new_landmarks = 0;
  long dropped = 0;
  double wall_s = 0.0;
  // Per scan: time, position error (m), heading error (rad), pose NEES (when scored).
  struct TracePoint {
    double t, position_error_m, heading_error_rad, nees;
  };
  std::vector<TracePoint> trace;
  // What the run produced, for later experiments (alignment between robots).
  LandmarkMap map;  // the final local map, in the robot's frame
  struct PoseSample {
    double t;
    Pose2 pose;
    Eigen::Matrix3d cov;
  };
  std::vector<PoseSample> poses;  // at every scan
  struct Sighting {
    double t;
    RobotId seen;
    double range, bearing;
  };
  std::vector<Sighting> sightings;              // of other robots
  std::optional<Pose2> origin_truth;            // true pose of the robot's frame, when known
  std::vector<Eigen::Vector2d> landmark_truth;  // of the world (index = signature)
};

// Runs the scenario once (its seed as given) and scores every robot.
std::vector<SlamRunResult> RunSlam(const Scenario& scenario, const SlamRunOptions& options);

// CSV header and row of a result.
std::string SlamCsvHeader();
std::string SlamCsvRow(const SlamRunResult& r);

}  // namespace mapmesh::lab
