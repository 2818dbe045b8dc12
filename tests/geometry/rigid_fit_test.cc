#include "common/geometry/rigid_fit.h"

#include <gtest/gtest.h>

#include <random>

namespace mapmesh {
namespace {

class RigidFitTest : public ::testing::TestWithParam<int> {};

TEST_P(RigidFitTest, RecoversAPlantedTransform) {
  std::mt19937_64 rng(GetParam());
  std::uniform_real_distribution<double> u(-50, 50), ua(-M_PI, M_PI);
  std::normal_distribution<double> noise(0.0, 0.01);
  const Pose2 truth{u(rng), u(rng), ua(rng)};
  std::vector<Eigen::Vector2d> src, dst;
  for (int i = 0; i < 30; ++i) {
    src.emplace_back(u(rng), u(rng));
    dst.push_back(truth.Apply(src.back()) + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  const auto fit = FitRigid2D(src, dst);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->x, truth.x, 0.02);
  EXPECT_NEAR(fit->y, truth.y, 0.02);
  EXPECT_NEAR(WrapAngle(fit->theta - truth.theta), 0.0, 1e-3);
}

INSTANTIATE_TEST_SUITE_P(Seeds, RigidFitTest, ::testing::Range(1, 11));

TEST(RigidFit, ExactForTwoPoints) {
  const Pose2 truth{1, -2, 0.7};
  const std::vector<Eigen::Vector2d> src{{0, 0}, {3, 1}};
  const auto fit = FitRigid2D(src, {truth.Apply(src[0]), truth.Apply(src[1])});
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->x, 1, 1e-12);
  EXPECT_NEAR(fit->theta, 0.7, 1e-12);
}

TEST(RigidFit, DegenerateInputs) {
  EXPECT_FALSE(FitRigid2D({{1, 1}}, {{2, 2}}).has_value());
  EXPECT_FALSE(FitRigid2D({{1, 1}, {1, 1}}, {{2, 2}, {3, 3}}).has_value());
  EXPECT_FALSE(FitRigid2D({{1, 1}, {2, 2}}, {{2, 2}}).has_value());
}

// The two-pair closed form agrees with the general fit, and both recover the planted pose.
TEST(RigidFit, TwoPairClosedFormMatchesTheGeneralFit) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-50, 50), ua(-M_PI, M_PI);
  for (int i = 0; i < 200; ++i) {
    const Pose2 t{u(rng), u(rng), ua(rng)};
    const Eigen::Vector2d b1(u(rng), u(rng)), b2(u(rng), u(rng));
    const auto closed = FitRigid2D(b1, b2, t.Apply(b1), t.Apply(b2));
    const auto general = FitRigid2D({b1, b2}, {t.Apply(b1), t.Apply(b2)});
    ASSERT_TRUE(closed && general);
    EXPECT_NEAR(closed->x, general->x, 1e-9);
    EXPECT_NEAR(closed->y, general->y, 1e-9);
    EXPECT_NEAR(WrapAngle(closed->theta - general->theta), 0.0, 1e-12);
    EXPECT_NEAR(WrapAngle(closed->theta - t.theta), 0.0, 1e-9);
  }
  EXPECT_FALSE(FitRigid2D(Eigen::Vector2d(2, 2), Eigen::Vector2d(2, 2), Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0))
                   .has_value());
}

}  // namespace
}  // namespace mapmesh
