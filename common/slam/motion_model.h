#pragma once
// Robot motion models with Jacobians. The feeder uses them to move the true robots, the
// agents to predict; both must agree, so they live here.

#include <Eigen/Core>

#include "common/geometry/pose2.h"

namespace mapmesh {

// Unicycle control: forward speed and turn rate, held constant over dt.
struct UnicycleControl {
  double v_mps = 0.0;
  double w_radps = 0.0;
};

// Unicycle motion over dt: thesis eq. 99, which tends to eq. 98 as w -> 0, evaluated in a
// form that stays exact near w = 0.
// Optional Jacobians: d(pose')/d(pose) (3x3) and d(pose')/d(v, w) (3x2).
Pose2 UnicycleMotion(const Pose2& pose, const UnicycleControl& u, double dt,
                     Eigen::Matrix3d* j_pose = nullptr,
                     Eigen::Matrix<double, 3, 2>* j_control = nullptr);

}  // namespace mapmesh
