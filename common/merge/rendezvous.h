#pragma once
// Frame alignment from a rendezvous (thesis 3.3.1, eq. 39-50; left as future work there):
// two robots range and bear to each other at about the same time. The two ranges are fused by
// their inverse variances (eq. 40), the relative heading follows from the two bearings
// (eq. 44: pi + bearing_12 - bearing_21), and with each robot's pose in its own map frame the
// transform between the map frames follows (eq. 45-50), with a covariance propagated from
// both poses and the four measurements.

#include <Eigen/Core>
#include <optional>

#include "common/geometry/pose2.h"

namespace mapmesh {

struct RendezvousInput {
  Pose2 pose1;  // robot 1 in map frame 1
  Eigen::Matrix3d cov1 = Eigen::Matrix3d::Zero();
  Pose2 pose2;  // robot 2 in map frame 2
  Eigen::Matrix3d cov2 = Eigen::Matrix3d::Zero();
  double range12 = 0.0, bearing12 = 0.0;  // robot 1's sighting of robot 2
  double range21 = 0.0, bearing21 = 0.0;  // robot 2's sighting of robot 1
  double sigma_range1 = 0.1, sigma_bearing1 = 0.02;
  double sigma_range2 = 0.1, sigma_bearing2 = 0.02;
};

struct RendezvousResult {
  Pose2 transform;  // maps frame 2 into frame 1
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double range = 0.0;               // the fused range (eq. 40)
  double range_disagreement = 0.0;  // |range12 - range21| in sigmas of their difference
};

// nullopt for non-finite input or non-positive range sigmas.
std::optional<RendezvousResult> RendezvousAlign(const RendezvousInput& in);

}  // namespace mapmesh
