#pragma once
// The filter noise the local-SLAM tests use: 0.03 m/s and 0.05 rad/s odometry over 0.1 s,
// 0.05 m and 1 degree range-bearing readings.

#include <Eigen/Core>
#include <cmath>

#include "common/slam/landmark_filter.h"

namespace mapmesh::testing {

inline FilterNoise TestFilterNoise() {
  FilterNoise n;
  n.control_cov = Eigen::Vector2d(0.03 * 0.03, 0.05 * 0.05).asDiagonal();
  n.obs_cov = Eigen::Vector2d(0.05 * 0.05, std::pow(DegToRad(1.0), 2)).asDiagonal();
  return n;
}

}  // namespace mapmesh::testing
