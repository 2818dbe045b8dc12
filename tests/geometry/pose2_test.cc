#include "common/geometry/pose2.h"

#include <gtest/gtest.h>

#include <random>

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

}  // namespace
}  // namespace mapmesh
