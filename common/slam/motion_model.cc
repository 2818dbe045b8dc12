#include "common/slam/motion_model.h"

#include <algorithm>
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
Pose2 UnicycleMotion(const Pose2& pose, const UnicycleControl& u, double dt, Eigen::Matrix3d* j_pose,
                     Eigen::Matrix<double, 3, 2>* j_control) {
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
    const double ds = SincDerivative(half) * 0.5 * dt;        // d sinc / d w
    const double da = 0.5 * dt;                               // d a / d w
    *j_control << dt * ca * s, d * (-sa * da * s + ca * ds),  //
        dt * sa * s, d * (ca * da * s + sa * ds),             //
        0, dt;
  }
  return out;
}

Pose2 AckermannMotion(const Pose2& pose, const AckermannControl& u, double dt, const AckermannParams& p,
                      Eigen::Matrix3d* j_pose, Eigen::Matrix<double, 3, 2>* j_control) {
  const double L = p.wheelbase_m, H = p.encoder_offset_m, a = p.laser_a_m, b = p.laser_b_m;
  const double t = std::tan(u.steering_rad);
  const double k = 1.0 / (1.0 - t * H / L);  // vc = k v
  const double vc = k * u.v_mps;
  const double c = std::cos(pose.theta), s = std::sin(pose.theta);
  const double fx = vc * c - vc / L * t * (a * s + b * c);
  const double fy = vc * s + vc / L * t * (a * c - b * s);
  const double fth = vc / L * t;
  const Pose2 out{pose.x + dt * fx, pose.y + dt * fy, WrapAngle(pose.theta + dt * fth)};
  if (j_pose) {
    *j_pose << 1, 0, dt * (-vc * s - vc / L * t * (a * c - b * s)),  //
        0, 1, dt * (vc * c + vc / L * t * (-a * s - b * c)),         //
        0, 0, 1;
  }
  if (j_control) {
    // d vc / d v = k;  d t / d s = 1 + t^2;  d k / d t = k^2 H / L.
    const double dt_ds = 1.0 + t * t;
    const double dvc_ds = u.v_mps * k * k * H / L * dt_ds;
    // f = vc * g(t): g_x = c - t (a s + b c) / L, g_y = s + t (a c - b s) / L, g_th = t / L.
    const double gx = c - t * (a * s + b * c) / L, gy = s + t * (a * c - b * s) / L, gth = t / L;
    const double dgx = -(a * s + b * c) / L * dt_ds, dgy = (a * c - b * s) / L * dt_ds, dgth = dt_ds / L;
    *j_control << dt * k * gx, dt * (dvc_ds * gx + vc * dgx),  //
        dt * k * gy, dt * (dvc_ds * gy + vc * dgy),            //
        dt * k * gth, dt * (dvc_ds * gth + vc * dgth);
  }
  return out;
}

Pose2 MoveRobot(const MotionModel& model, const Pose2& pose, const OdometryControl& u, double dt,
                Eigen::Matrix3d* j_pose, Eigen::Matrix<double, 3, 2>* j_control) {
  if (model.kind == MotionModel::Kind::kAckermann) {
    return AckermannMotion(pose, {u.v_mps, u.steering_rad}, dt, model.ackermann, j_pose, j_control);
  }
  return UnicycleMotion(pose, {u.v_mps, u.w_radps}, dt, j_pose, j_control);
}

namespace {

// d(pose rate)/d(controls) at pose: the unicycle's, or the car's (its step is Euler's, so its
// control Jacobian over 1 s is the rate's).
Eigen::Matrix<double, 3, 2> ControlRate(const MotionModel& model, const Pose2& pose, const OdometryControl& u) {
  Eigen::Matrix<double, 3, 2> b;
  if (model.kind == MotionModel::Kind::kAckermann) {
    AckermannMotion(pose, {u.v_mps, u.steering_rad}, 1.0, model.ackermann, nullptr, &b);
    return b;
  }
  b << std::cos(pose.theta), 0, std::sin(pose.theta), 0, 0, 1;
  return b;
}

// The model's turn rate (rad/s).
double TurnRate(const MotionModel& model, const OdometryControl& u) {
  if (model.kind == MotionModel::Kind::kAckermann) {
    const AckermannParams& p = model.ackermann;
    const double t = std::tan(u.steering_rad);
    return u.v_mps / (1.0 - t * p.encoder_offset_m / p.wheelbase_m) * t / p.wheelbase_m;
  }
  return u.w_radps;
}

}  // namespace

Eigen::Matrix3d MotionNoise(const MotionModel& model, const Pose2& pose, const OdometryControl& u, double dt,
                            const Eigen::Matrix2d& density) {
  Eigen::Matrix3d q = Eigen::Matrix3d::Zero();
  if (!(dt > 0)) return q;
  // Gauss-Legendre on [-1, 1], 5 nodes: exact for polynomials of degree 9.
  static constexpr double kNode[5] = {-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831,
                                      0.9061798459386640};
  static constexpr double kWeight[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665,
                                        0.2369268850561891};
  const double turned = std::abs(TurnRate(model, u)) * dt;
  const int panels = static_cast<int>(std::clamp(std::ceil(turned), 1.0, 64.0));
  const double h = dt / panels;
  for (int p = 0; p < panels; ++p) {
    for (int k = 0; k < 5; ++k) {
      const double s = h * (p + 0.5 * (kNode[k] + 1.0));
      const Pose2 at = MoveRobot(model, pose, u, s);
      Eigen::Matrix3d phi;
      MoveRobot(model, at, u, dt - s, &phi);
      const Eigen::Matrix<double, 3, 2> g = phi * ControlRate(model, at, u);
      q.noalias() += (0.5 * h * kWeight[k]) * g * density * g.transpose();
    }
  }
  return 0.5 * (q + q.transpose());
}

}  // namespace mapmesh
