#include "common/slam/motion_model.h"

#include <cmath>

namespace mapmesh {

Pose2 UnicycleMotion(const Pose2& pose, const UnicycleControl& u, double dt,
                     Eigen::Matrix3d* j_pose, Eigen::Matrix<double, 3, 2>* j_control) {
  const double v = u.v_mps, w = u.w_radps, th = pose.theta;
  const double s0 = std::sin(th), c0 = std::cos(th);
  // Below this turn rate eq. 99 loses precision; use its limit (eq. 98) and its Taylor
  // expansion for the derivative with respect to w.
  constexpr double kSmallW = 1e-6;
  Pose2 out;
  if (std::abs(w) < kSmallW) {
    out = {pose.x + v * dt * c0, pose.y + v * dt * s0, WrapAngle(th + w * dt)};
    if (j_pose) {
      *j_pose << 1, 0, -v * dt * s0,  //
          0, 1, v * dt * c0,          //
          0, 0, 1;
    }
    if (j_control) {
      *j_control << dt * c0, -0.5 * v * dt * dt * s0,  //
          dt * s0, 0.5 * v * dt * dt * c0,             //
          0, dt;
    }
    return out;
  }
  const double th1 = th + w * dt;
  const double s1 = std::sin(th1), c1 = std::cos(th1);
  const double r = v / w;
  out = {pose.x + r * (s1 - s0), pose.y + r * (c0 - c1), WrapAngle(th1)};
  if (j_pose) {
    *j_pose << 1, 0, r * (c1 - c0),  //
        0, 1, r * (s1 - s0),         //
        0, 0, 1;
  }
  if (j_control) {
    const double dr_dw = -v / (w * w);
    *j_control << (s1 - s0) / w, dr_dw * (s1 - s0) + r * c1 * dt,  //
        (c0 - c1) / w, dr_dw * (c0 - c1) + r * s1 * dt,             //
        0, dt;
  }
  return out;
}

}  // namespace mapmesh
