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
Pose2 UnicycleMotion(const Pose2& pose, const UnicycleControl& u, double dt, Eigen::Matrix3d* j_pose = nullptr,
                     Eigen::Matrix<double, 3, 2>* j_control = nullptr);

// Car-like (Ackermann) vehicle of Victoria Park (Guivant & Nebot 2001): the state is the
// laser's position and the vehicle heading; the speed is measured at the rear-left wheel.
struct AckermannParams {
  double wheelbase_m = 2.83;       // L
  double encoder_offset_m = 0.76;  // H: lateral offset of the speed encoder from the axle centre
  double laser_a_m = 3.78;         // a: laser ahead of the rear axle
  double laser_b_m = 0.50;         // b: laser left of the centre line
  static AckermannParams VictoriaPark() { return {}; }
};

struct AckermannControl {
  double v_mps = 0.0;         // encoder speed
  double steering_rad = 0.0;  // front-wheel steering angle
};

// One step of the Victoria Park vehicle model:
//   vc = v / (1 - tan(s) H / L)
//   x' = x + dt (vc cos(phi) - vc/L tan(s) (a sin(phi) + b cos(phi)))
//   y' = y + dt (vc sin(phi) + vc/L tan(s) (a cos(phi) - b sin(phi)))
//   phi' = phi + dt vc/L tan(s)
// Optional Jacobians: d(pose')/d(pose) (3x3) and d(pose')/d(v, s) (3x2).
Pose2 AckermannMotion(const Pose2& pose, const AckermannControl& u, double dt, const AckermannParams& params,
                      Eigen::Matrix3d* j_pose = nullptr, Eigen::Matrix<double, 3, 2>* j_control = nullptr);

// Which model moves a robot, and its parameters; chosen per robot by the scenario.
struct MotionModel {
  enum class Kind { kUnicycle, kAckermann } kind = Kind::kUnicycle;
  AckermannParams ackermann;
};

// A control as odometry reports it: (v, w) for a unicycle, (v, steering) for a car.
struct OdometryControl {
  double v_mps = 0.0;
  double w_radps = 0.0;
  double steering_rad = 0.0;
  // The model's 2-vector of controls: (v, w) or (v, steering).
  Eigen::Vector2d Vector(const MotionModel& m) const {
    return m.kind == MotionModel::Kind::kUnicycle ? Eigen::Vector2d(v_mps, w_radps)
                                                  : Eigen::Vector2d(v_mps, steering_rad);
  }
};

// Moves pose by one control over dt with the given model. j_control is with respect to the
// model's control vector (OdometryControl::Vector).
Pose2 MoveRobot(const MotionModel& model, const Pose2& pose, const OdometryControl& u, double dt,
                Eigen::Matrix3d* j_pose = nullptr, Eigen::Matrix<double, 3, 2>* j_control = nullptr);

// The covariance a pose gains moving by u over dt when the controls err by white noise of
// spectral density `density` (2x2, of the model's control vector, in control^2 * s: the
// covariance of the mean control over an interval T is density / T):
//   Q(dt) = integral over s in [0, dt] of Phi(dt, s) B(s) density B(s)^T Phi(dt, s)^T,
// with B(s) how the pose's rate depends on the controls at the pose reached at s, and Phi(dt, s)
// the pose Jacobian of the rest of the motion (Gauss-Legendre, 5 nodes per radian turned).
// Unlike J density/dt J^T of one step, which is singular (the arc's sideways error is tied to
// its heading error), it is the same whether an interval is integrated whole or in pieces:
// Q(dt) = Phi Q(dt1) Phi^T + Q(dt - dt1), so a filter's uncertainty does not depend on the
// odometry's rate. As dt -> 0 it tends to J density/dt J^T.
Eigen::Matrix3d MotionNoise(const MotionModel& model, const Pose2& pose, const OdometryControl& u, double dt,
                            const Eigen::Matrix2d& density);

}  // namespace mapmesh
