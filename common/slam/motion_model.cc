#include "common/slam/motion_model.h"

#include <cmath>

namespace mapmesh {
namespace {

// sin(u)/u and its derivative, with Taylor series near 0 (no cancellation).
double Sinc(double u) {
  if (std::abs(u) < 1e-4) return 1.0 - u * u / 6.0 + u * u * u * u / 120.0;
  return std::sin(u) / u;
}
double SincDerivative(double u) {
  if (std::abs(u) < 1e-4) return -u / 3.0 + u * u * u / 30.0;
  return (u * std::cos(u) - std::sin(u)) / (u * u);
}

}  // namespace

// Eq. 99 rewritten with sin(a + b) - sin(a) = 2 cos(a + b/2) sin(b/2) (and its cosine twin):
//   x' = x + v dt cos(th + w dt / 2) sinc(w dt / 2),  y' = y + v dt sin(th + w dt / 2) sinc(w dt / 2).
// It is exactly eq. 99 for w != 0, tends to eq. 98 as w -> 0, and loses no precision near 0.
Pose2 UnicycleMotion(const Pose2& pose, const UnicycleControl& u, double dt,
                     Eigen::Matrix3d* j_pose, Eigen::Matrix<double, 3, 2>* j_control) {
  const double half = 0.5 * u.w_radps * dt;
  const double a = pose.theta + half;
  const double ca = std::cos(a), sa = std::sin(a);
  const double s = Sinc(half);
  const double d = u.v_mps * dt;
  const Pose2 out{pose.x + d * ca * s, pose.y + d * sa * s, WrapAngle(pose.theta + u.w_radps * dt)};
  if (j_pose) {
    *j_pose << 1, 0, -d * sa * s,  //
        0, 1, d * ca * s,          //
        0, 0, 1;
  }
  if (j_control) {
    const double ds = SincDerivative(half) * 0.5 * dt;  // d sinc / d w
    const double da = 0.5 * dt;                         // d a / d w
    *j_control << dt * ca * s, d * (-sa * da * s + ca * ds),  //
        dt * sa * s, d * (ca * da * s + sa * ds),             //
        0, dt;
  }
  return out;
}

}  // namespace mapmesh
