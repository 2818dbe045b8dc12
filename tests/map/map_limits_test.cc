#include "common/map/map_limits.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

LandmarkMap Grid(int n, double spacing_m, double sigma_m) {
  LandmarkMap m;
  for (int i = 0; i < n; ++i) {
    m.landmarks.push_back({static_cast<std::uint32_t>(i),
                           -1,
                           {spacing_m * i, -spacing_m * i},
                           sigma_m * sigma_m * Eigen::Matrix2d::Identity()});
  }
  return m;
}

TEST(MapLimits, AMapWithinEveryLimitPasses) {
  MapLimits limits;
  limits.max_landmarks = 10;
  limits.world_radius_m = 100.0;
  limits.max_sigma_m = 2.0;
  EXPECT_EQ(CheckMapLimits(Grid(10, 10.0, 2.0), limits), MapLimitViolation::kNone);  // on every bound
  EXPECT_EQ(CheckMapLimits(LandmarkMap{}, limits), MapLimitViolation::kNone);
}

TEST(MapLimits, EachLimitIsItsOwnReason) {
  MapLimits limits;
  limits.max_landmarks = 10;
  limits.world_radius_m = 100.0;
  limits.max_sigma_m = 2.0;
  EXPECT_EQ(CheckMapLimits(Grid(11, 1.0, 0.1), limits), MapLimitViolation::kTooManyLandmarks);
  EXPECT_EQ(CheckMapLimits(Grid(3, 50.001, 0.1), limits), MapLimitViolation::kOutOfWorld);  // (100.002, -100.002)
  LandmarkMap m = Grid(3, 1.0, 0.1);
  m.landmarks[1].cov(1, 1) = 4.01;
  EXPECT_EQ(CheckMapLimits(m, limits), MapLimitViolation::kCovarianceTooLarge);
  // Size first: a huge map is refused before any of its landmarks is looked at.
  EXPECT_EQ(CheckMapLimits(Grid(20, 50.0, 9.0), limits), MapLimitViolation::kTooManyLandmarks);
  EXPECT_EQ(ToString(MapLimitViolation::kOutOfWorld), "out_of_world");
}

// A submap (issue J1) is held to the same limits in its own frame: its end pose and landmarks
// within the world radius, each position's standard deviation (not the end heading's) within
// max_sigma_m.
TEST(MapLimits, ASubmapIsHeldToTheSameLimits) {
  MapLimits limits;
  limits.max_landmarks = 2;
  limits.world_radius_m = 100.0;
  limits.max_sigma_m = 2.0;
  WireSubmap s;
  s.keys = {1, 2};
  s.x = Eigen::VectorXd::Zero(7);
  s.x << 100.0, -100.0, 3.0, 99.0, 0.0, 0.0, -100.0;  // on the bound
  Eigen::MatrixXd p = Eigen::MatrixXd::Identity(7, 7) * 3.99;
  p(2, 2) = 50.0;  // the heading's variance is no position's
  ASSERT_TRUE(s.SetCovariance(p));
  EXPECT_EQ(CheckSubmapLimits(s, limits), MapLimitViolation::kNone);
  WireSubmap far = s;
  far.x(0) = 100.01;  // the end pose
  EXPECT_EQ(CheckSubmapLimits(far, limits), MapLimitViolation::kOutOfWorld);
  far = s;
  far.x(6) = -100.01;  // the last landmark
  EXPECT_EQ(CheckSubmapLimits(far, limits), MapLimitViolation::kOutOfWorld);
  WireSubmap vague = s;
  p(5, 5) = 4.1;
  ASSERT_TRUE(vague.SetCovariance(p));
  EXPECT_EQ(CheckSubmapLimits(vague, limits), MapLimitViolation::kCovarianceTooLarge);
  limits.max_landmarks = 1;
  EXPECT_EQ(CheckSubmapLimits(vague, limits), MapLimitViolation::kTooManyLandmarks);
}

}  // namespace
}  // namespace mapmesh
