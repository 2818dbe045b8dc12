#pragma once
// The baseline estimator (`slam: dead_reckoning`): the pose is integrated from odometry
// alone and each landmark is the average of its observations projected through that pose.
// It ignores pose uncertainty, so its covariances are optimistic; it exists as a simple,
// honest reference for the filters that replace it.

#include <Eigen/Core>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/slam/local_mapper.h"
#include "common/slam/motion_model.h"
#include "common/types/messages.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

struct DeadReckoningOptions {
  MotionModel motion;                 // how odometry moves the pose (the robot's)
  double sigma_range_m = 0.05;        // sensor range noise, for landmark covariances (the robot's)
  double sigma_bearing_rad = 0.0175;  // sensor bearing noise (the robot's)
  double association_gate_m = 1.0;    // agent.association_gate_m: without signatures, join the nearest landmark
                                      // within this

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md).
  template <typename Reader>
  void Read(Reader& r) {
    r.GetPositiveUpTo("association_gate_m", association_gate_m, limits::kMaxLengthM);
  }
};

class DeadReckoningMapper : public LocalMapper {
 public:
  explicit DeadReckoningMapper(const DeadReckoningOptions& options);

  // Moves the pose by one odometry interval (no noise).
  void Predict(const OdometryControl& u, double dt) override;
  // Adds the landmark observations of a scan (robot sightings are ignored).
  void Observe(const std::vector<Observation>& obs, double stamp = 0.0) override;

  Pose2 pose() const override { return pose_; }
  // Dead reckoning keeps no pose uncertainty.
  Eigen::Matrix3d pose_cov() const override { return Eigen::Matrix3d::Zero(); }
  // The current map: one landmark per signature (or per nearest-neighbour cluster).
  LandmarkMap Map() const override;
  std::size_t size() const override { return tracks_.size(); }
  const MapperStats& stats() const override { return stats_; }

 private:
  struct Track {
    std::uint32_t id = 0;
    std::int32_t signature = -1;
    std::uint32_t n = 0;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
    Eigen::Matrix2d sum_outer = Eigen::Matrix2d::Zero();
    Eigen::Matrix2d sum_noise = Eigen::Matrix2d::Zero();  // sum of projected sensor covariances
    Eigen::Vector2d Mean() const { return sum / n; }
  };

  DeadReckoningOptions options_;
  Pose2 pose_;
  std::vector<Track> tracks_;
  std::unordered_map<std::int32_t, std::size_t> by_signature_;
  MapperStats stats_;
};

}  // namespace mapmesh
