#pragma once
// SE(2) poses and angle helpers.

#include <Eigen/Core>
#include <cmath>
#include <numbers>

namespace mapmesh {

// Wraps an angle to [-pi, pi).
inline double WrapAngle(double a) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  a = std::fmod(a + std::numbers::pi, kTwoPi);
  if (a < 0) a += kTwoPi;
  return a - std::numbers::pi;
}

inline constexpr double DegToRad(double d) { return d * std::numbers::pi / 180.0; }
inline constexpr double RadToDeg(double r) { return r * 180.0 / std::numbers::pi; }

// A rigid 2D pose (x, y, theta): maps points from its own frame into the parent frame.
struct Pose2 {
  double x = 0.0;
  double y = 0.0;
  double theta = 0.0;

  // Maps a point given in this pose's frame into the parent frame. When asked, also the
  // Jacobians of the result with respect to this pose (x, y, theta) and to the point.
  Eigen::Vector2d Apply(const Eigen::Vector2d& p, Eigen::Matrix<double, 2, 3>* j_pose = nullptr,
                        Eigen::Matrix2d* j_point = nullptr) const;
  // The inverse map (GTSAM's transformTo): a parent-frame point in this pose's frame,
  // R^T (p - t). When asked, also the Jacobians of the result with respect to this pose
  // (x, y, theta) and to the point.
  Eigen::Vector2d TransformTo(const Eigen::Vector2d& p, Eigen::Matrix<double, 2, 3>* j_pose = nullptr,
                              Eigen::Matrix2d* j_point = nullptr) const;
  // Composition: (this * other) maps other's frame into this pose's parent frame.
  Pose2 operator*(const Pose2& o) const {
    const Eigen::Vector2d t = Apply({o.x, o.y});
    return {t.x(), t.y(), WrapAngle(theta + o.theta)};
  }
  // The inverse transform: maps parent-frame points into this pose's frame.
  Pose2 Inverse() const {
    const double c = std::cos(theta), s = std::sin(theta);
    return {-c * x - s * y, s * x - c * y, WrapAngle(-theta)};
  }
  Eigen::Matrix2d Rotation() const;
  Eigen::Vector3d Vector() const { return {x, y, theta}; }
  // The pose moved by a step d of its parameters (x, y, theta), the angle wrapped: the
  // retraction that ends every least-squares step (GTSAM's retract), whose Jacobians are all with
  // respect to these three parameters.
  Pose2 Retract(const Eigen::Vector3d& d) const { return {x + d(0), y + d(1), WrapAngle(theta + d(2))}; }
};

// A pose with its sine and cosine evaluated once, for loops that map many points: Apply and
// Rotation give exactly Pose2's results.
class PoseMap2 {
 public:
  explicit PoseMap2(const Pose2& p) : x_(p.x), y_(p.y), c_(std::cos(p.theta)), s_(std::sin(p.theta)) {}
  Eigen::Vector2d Apply(const Eigen::Vector2d& p, Eigen::Matrix<double, 2, 3>* j_pose = nullptr,
                        Eigen::Matrix2d* j_point = nullptr) const {
    if (j_pose) {
      *j_pose << 1.0, 0.0, -s_ * p.x() - c_ * p.y(),  //
          0.0, 1.0, c_ * p.x() - s_ * p.y();
    }
    if (j_point) *j_point << c_, -s_, s_, c_;
    return {x_ + c_ * p.x() - s_ * p.y(), y_ + s_ * p.x() + c_ * p.y()};
  }
  Eigen::Matrix2d Rotation() const {
    Eigen::Matrix2d r;
    r << c_, -s_, s_, c_;
    return r;
  }

 private:
  double x_, y_, c_, s_;
};

inline Eigen::Vector2d Pose2::Apply(const Eigen::Vector2d& p, Eigen::Matrix<double, 2, 3>* j_pose,
                                    Eigen::Matrix2d* j_point) const {
  return PoseMap2(*this).Apply(p, j_pose, j_point);
}

inline Eigen::Matrix2d Pose2::Rotation() const { return PoseMap2(*this).Rotation(); }

inline Eigen::Vector2d Pose2::TransformTo(const Eigen::Vector2d& p, Eigen::Matrix<double, 2, 3>* j_pose,
                                          Eigen::Matrix2d* j_point) const {
  const double c = std::cos(theta), s = std::sin(theta);
  const double dx = p.x() - x, dy = p.y() - y;
  const Eigen::Vector2d q(c * dx + s * dy, -s * dx + c * dy);
  if (j_pose) {
    // d q / d t = -R^T; d q / d theta = dR^T/dtheta (p - t) = (q.y, -q.x).
    *j_pose << -c, -s, q.y(),  //
        s, -c, -q.x();
  }
  if (j_point) *j_point << c, s, -s, c;
  return q;
}

// The pose a of the way from p to q (a in [0, 1]): positions linearly, the heading along the
// shorter arc.
inline Pose2 Interpolate(const Pose2& p, const Pose2& q, double a) {
  return {p.x + a * (q.x - p.x), p.y + a * (q.y - p.y), WrapAngle(p.theta + a * WrapAngle(q.theta - p.theta))};
}

// a * b with the Jacobians of the result with respect to a and to b.
inline Pose2 Compose(const Pose2& a, const Pose2& b, Eigen::Matrix3d* j_a, Eigen::Matrix3d* j_b) {
  if (j_a) {
    Eigen::Matrix<double, 2, 3> j_t;
    a.Apply({b.x, b.y}, &j_t);
    j_a->topRows<2>() = j_t;
    j_a->row(2) << 0, 0, 1;
  }
  if (j_b) {
    Eigen::Matrix2d r;
    a.Apply({b.x, b.y}, nullptr, &r);
    j_b->setIdentity();
    j_b->topLeftCorner<2, 2>() = r;
  }
  return a * b;
}

// a^-1 with its Jacobian with respect to a.
inline Pose2 Invert(const Pose2& a, Eigen::Matrix3d* j_a) {
  const double c = std::cos(a.theta), s = std::sin(a.theta);
  if (j_a) {
    *j_a << -c, -s, s * a.x - c * a.y,  //
        s, -c, c * a.x + s * a.y,       //
        0, 0, -1;
  }
  return a.Inverse();
}

// a^-1 * b, the pose of b in a's frame (GTSAM's between), with its Jacobians with respect to a
// and to b: d = R(a)^T (t_b - t_a), theta = wrap(theta_b - theta_a).
inline Pose2 Between(const Pose2& a, const Pose2& b, Eigen::Matrix3d* j_a = nullptr, Eigen::Matrix3d* j_b = nullptr) {
  const double c = std::cos(a.theta), s = std::sin(a.theta);
  const double dx = b.x - a.x, dy = b.y - a.y;
  const Pose2 out{c * dx + s * dy, -s * dx + c * dy, WrapAngle(b.theta - a.theta)};
  if (j_a) {
    *j_a << -c, -s, out.y,  //
        s, -c, -out.x,      //
        0, 0, -1;
  }
  if (j_b) {
    *j_b << c, s, 0,  //
        -s, c, 0,     //
        0, 0, 1;
  }
  return out;
}

}  // namespace mapmesh
