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
  std::uint32_t id = 0;                               // unique within its map
  std::int32_t signature = -1;                        // sensor identity if known, else -1
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();     // m
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();  // m^2, marginal 2x2 covariance
};

// A set of landmarks in one frame.
struct LandmarkMap {
  std::vector<Landmark> landmarks;
  // How precisely the map knows its own local shape, when its maker could tell (0: unknown):
  // the standard deviation, per axis, of a landmark relative to its nearest neighbour over
  // the square root of 2, at the 90th percentile over the map. In a SLAM map the marginal
  // covariances are dominated by the robot's accumulated pose error, which all nearby
  // landmarks share; this is the part that does not cancel between neighbours, and what map
  // alignment needs to compare shapes.
  double shape_sigma_m = 0.0;

  std::size_t size() const { return landmarks.size(); }
  bool empty() const { return landmarks.empty(); }
  // Returns the landmark with this id, if present (linear search).
  const Landmark* Find(std::uint32_t id) const;
};

// True when cov is finite, symmetric (to 1e-9 relative) and positive semi-definite.
bool IsValidCovariance(const Eigen::Matrix2d& cov);

// The map expressed in a parent frame: means mapped by `pose`, covariances rotated.
LandmarkMap TransformMap(const LandmarkMap& map, const Pose2& pose);

// The centroid of a map's landmarks (the origin for an empty map).
Eigen::Vector2d Centroid(const LandmarkMap& m);

// The map with every signature cleared: what geometry-only alignment and matching see.
LandmarkMap WithoutSignatures(LandmarkMap map);

}  // namespace mapmesh
