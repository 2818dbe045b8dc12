#pragma once
// The landmark map value type shared by SLAM, merging, the wire codec and evaluation.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"

namespace mapmesh {

// One landmark estimate in its map's frame.
struct Landmark {
  std::uint32_t id = 0;                         // unique within its map
  std::int32_t signature = -1;                  // sensor identity if known, else -1
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();  // m
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();  // m^2, marginal 2x2 covariance
};

// A set of landmarks in one frame.
struct LandmarkMap {
  std::vector<Landmark> landmarks;

  std::size_t size() const { return landmarks.size(); }
  bool empty() const { return landmarks.empty(); }
  // Returns the landmark with this id, if present (linear search).
  const Landmark* Find(std::uint32_t id) const;
};

// True when cov is finite, symmetric (to 1e-9 relative) and positive semi-definite.
bool IsValidCovariance(const Eigen::Matrix2d& cov);

// The map expressed in a parent frame: means mapped by `pose`, covariances rotated.
LandmarkMap TransformMap(const LandmarkMap& map, const Pose2& pose);

}  // namespace mapmesh
