#include "common/geometry/pose2.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <utility>

namespace mapmesh {
namespace {

TEST(WrapAngle, MapsIntoHalfOpenInterval) {
  EXPECT_DOUBLE_EQ(WrapAngle(0.0), 0.0);
  EXPECT_NEAR(WrapAngle(3 * M_PI / 2), -M_PI / 2, 1e-12);
  EXPECT_NEAR(WrapAngle(-3 * M_PI / 2), M_PI / 2, 1e-12);
  EXPECT_NEAR(WrapAngle(M_PI), -M_PI, 1e-12);
  EXPECT_NEAR(WrapAngle(21 * M_PI + 0.25), -M_PI + 0.25, 1e-9);
}

TEST(Pose2, ApplyRotatesThenTranslates) {
  const Pose2 p{1.0, 2.0, M_PI / 2};
  const Eigen::Vector2d q = p.Apply({1.0, 0.0});
  EXPECT_NEAR(q.x(), 1.0, 1e-12);
  EXPECT_NEAR(q.y(), 3.0, 1e-12);
}

TEST(Pose2, ComposeAndInverseAreConsistentOnRandomPoses) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-10, 10), ua(-M_PI, M_PI);
  for (int i = 0; i < 200; ++i) {
    const Pose2 a{u(rng), u(rng), ua(rng)}, b{u(rng), u(rng), ua(rng)};
    const Eigen::Vector2d p(u(rng), u(rng));
    // (a * b).Apply(p) == a.Apply(b.Apply(p))
    EXPECT_TRUE(((a * b).Apply(p) - a.Apply(b.Apply(p))).norm() < 1e-9);
    // a^-1 * a is the identity.
    const Pose2 e = a.Inverse() * a;
    EXPECT_NEAR(e.x, 0.0, 1e-9);
    EXPECT_NEAR(e.y, 0.0, 1e-9);
    EXPECT_NEAR(WrapAngle(e.theta), 0.0, 1e-12);
    EXPECT_TRUE((a.Inverse().Apply(a.Apply(p)) - p).norm() < 1e-9);
  }
}

// Apply's Jacobians against central differences, on seeded random poses and points.
// Central differences of a map f(pose, point) -> R^2 with respect to the pose (x, y, theta) and
// to the point.
template <typename F>
std::pair<Eigen::Matrix<double, 2, 3>, Eigen::Matrix2d> NumericalJacobians(const F& f, const Pose2& t,
                                                                           const Eigen::Vector2d& p) {
  constexpr double kH = 1e-6;
  Eigen::Matrix<double, 2, 3> j_pose;
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d lo = t.Vector(), hi = t.Vector();
    lo(k) -= kH;
    hi(k) += kH;
    j_pose.col(k) = (f(Pose2{hi(0), hi(1), hi(2)}, p) - f(Pose2{lo(0), lo(1), lo(2)}, p)) / (2 * kH);
  }
  Eigen::Matrix2d j_point;
  for (int k = 0; k < 2; ++k) {
    Eigen::Vector2d lo = p, hi = p;
    lo(k) -= kH;
    hi(k) += kH;
    j_point.col(k) = (f(t, hi) - f(t, lo)) / (2 * kH);
  }
  return {j_pose, j_point};
}

// Over 200 seeded random poses and points: the Jacobians that map(pose, point, j_pose, j_point)
// returns match central differences of map(pose, point).
template <typename Map>
void ExpectJacobiansMatchNumericalDifferences(const Map& map, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-50, 50), ua(-M_PI, M_PI);
  for (int i = 0; i < 200; ++i) {
    const Pose2 t{u(rng), u(rng), ua(rng)};
    const Eigen::Vector2d p(u(rng), u(rng));
    Eigen::Matrix<double, 2, 3> j_pose;
    Eigen::Matrix2d j_point;
    EXPECT_EQ(map(t, p, &j_pose, &j_point), map(t, p, nullptr, nullptr));
    const auto [num_pose, num_point] = NumericalJacobians(
        [&](const Pose2& a, const Eigen::Vector2d& b) { return map(a, b, nullptr, nullptr); }, t, p);
    EXPECT_LT((j_pose - num_pose).cwiseAbs().maxCoeff(), 1e-6) << "pose " << i;
    EXPECT_LT((j_point - num_point).cwiseAbs().maxCoeff(), 1e-6) << "point " << i;
  }
}

// Retract moves the parameters the Jacobians are taken against: x and y exactly by the step,
// the angle by it and wrapped; so to first order a point maps as Apply's pose Jacobian says.
TEST(Pose2, RetractStepsTheParametersAndMatchesApplysPoseJacobian) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-10, 10), ua(-M_PI, M_PI), step(-4.0, 4.0);
  for (int i = 0; i < 200; ++i) {
    const Pose2 p{u(rng), u(rng), ua(rng)};
    const Eigen::Vector3d d(step(rng), step(rng), step(rng));
    const Pose2 q = p.Retract(d);
    EXPECT_EQ(q.x, p.x + d(0));
    EXPECT_EQ(q.y, p.y + d(1));
    EXPECT_GE(q.theta, -M_PI);
    EXPECT_LT(q.theta, M_PI);
    EXPECT_NEAR(std::remainder(q.theta - (p.theta + d(2)), 2 * M_PI), 0.0, 1e-12);
    const Pose2 same = p.Retract(Eigen::Vector3d::Zero());
    EXPECT_EQ(same.x, p.x);
    EXPECT_NEAR(same.theta, p.theta, 1e-15);

    const Eigen::Vector2d point(u(rng), u(rng));
    Eigen::Matrix<double, 2, 3> j;
    const Eigen::Vector2d at = p.Apply(point, &j);
    const Eigen::Vector3d small = 1e-6 * d;
    const Eigen::Vector2d moved = p.Retract(small).Apply(point);
    EXPECT_LT((moved - at - j * small).norm(), 1e-9) << i;
  }
  const Pose2 wraps = Pose2{0.0, 0.0, 3.0}.Retract({0.0, 0.0, 0.5});
  EXPECT_NEAR(wraps.theta, 3.5 - 2 * M_PI, 1e-12);
}

TEST(Pose2, ApplyJacobiansMatchNumericalDifferences) {
  ExpectJacobiansMatchNumericalDifferences([](const Pose2& t, const Eigen::Vector2d& p, Eigen::Matrix<double, 2, 3>* jt,
                                              Eigen::Matrix2d* jp) { return t.Apply(p, jt, jp); },
                                           11);
}

// TransformTo is Inverse().Apply, and its Jacobians match central differences, on seeded random
// poses and points.
TEST(Pose2, TransformToIsTheInverseMapAndItsJacobiansMatchNumericalDifferences) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-50, 50), ua(-M_PI, M_PI);
  for (int i = 0; i < 200; ++i) {
    const Pose2 t{u(rng), u(rng), ua(rng)};
    const Eigen::Vector2d p(u(rng), u(rng));
    const Eigen::Vector2d q = t.TransformTo(p);
    EXPECT_LT((q - t.Inverse().Apply(p)).norm(), 1e-9);
    EXPECT_LT((t.Apply(q) - p).norm(), 1e-9);
  }
  ExpectJacobiansMatchNumericalDifferences([](const Pose2& t, const Eigen::Vector2d& p, Eigen::Matrix<double, 2, 3>* jt,
                                              Eigen::Matrix2d* jp) { return t.TransformTo(p, jt, jp); },
                                           23);
}

// Between is a^-1 * b, and its Jacobians match central differences (the heading differences
// wrapped), on seeded random poses.
TEST(Pose2, BetweenIsTheRelativePoseAndItsJacobiansMatchNumericalDifferences) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-50, 50), ua(-M_PI, M_PI);
  constexpr double kH = 1e-6;
  auto diff = [](const Pose2& hi, const Pose2& lo) -> Eigen::Vector3d {
    return Eigen::Vector3d(hi.x - lo.x, hi.y - lo.y, WrapAngle(hi.theta - lo.theta)) / (2 * kH);
  };
  for (int i = 0; i < 200; ++i) {
    const Pose2 a{u(rng), u(rng), ua(rng)}, b{u(rng), u(rng), ua(rng)};
    Eigen::Matrix3d j_a, j_b;
    const Pose2 d = Between(a, b, &j_a, &j_b);
    const Pose2 ref = a.Inverse() * b;
    EXPECT_NEAR(d.x, ref.x, 1e-9);
    EXPECT_NEAR(d.y, ref.y, 1e-9);
    EXPECT_NEAR(WrapAngle(d.theta - ref.theta), 0.0, 1e-12);
    const Pose2 back = a * d;  // a * (a^-1 b) = b
    EXPECT_NEAR(back.x, b.x, 1e-9);
    EXPECT_NEAR(back.y, b.y, 1e-9);
    Eigen::Matrix3d num_a, num_b;
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d lo = a.Vector(), hi = a.Vector();
      lo(k) -= kH;
      hi(k) += kH;
      num_a.col(k) = diff(Between({hi(0), hi(1), hi(2)}, b), Between({lo(0), lo(1), lo(2)}, b));
      lo = b.Vector();
      hi = b.Vector();
      lo(k) -= kH;
      hi(k) += kH;
      num_b.col(k) = diff(Between(a, {hi(0), hi(1), hi(2)}), Between(a, {lo(0), lo(1), lo(2)}));
    }
    EXPECT_LT((j_a - num_a).cwiseAbs().maxCoeff(), 1e-5) << "a " << i;
    EXPECT_LT((j_b - num_b).cwiseAbs().maxCoeff(), 1e-5) << "b " << i;
  }
}

}  // namespace
}  // namespace mapmesh
