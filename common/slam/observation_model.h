#pragma once
// Range-bearing observation of a point landmark (thesis eq. 100) and its inverse, used to
// initialise landmarks, both with Jacobians.

#include <Eigen/Core>

#include "common/geometry/pose2.h"

namespace mapmesh {

using Matrix23 = Eigen::Matrix<double, 2, 3>;

// z = [range, bearing] of landmark m seen from robot: r = |m - p|, b = wrap(atan2 - theta).
// Optional Jacobians with respect to the robot pose (2x3) and the landmark (2x2).
Eigen::Vector2d ObserveRangeBearing(const Pose2& robot, const Eigen::Vector2d& landmark, Matrix23* h_robot = nullptr,
                                    Eigen::Matrix2d* h_landmark = nullptr);

// The landmark position that z = [range, bearing] puts at, seen from robot.
// Optional Jacobians with respect to the robot pose (2x3) and z (2x2).
Eigen::Vector2d InverseRangeBearing(const Pose2& robot, const Eigen::Vector2d& z, Matrix23* g_robot = nullptr,
                                    Eigen::Matrix2d* g_z = nullptr);

}  // namespace mapmesh
