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
  // Issue R3: a landmark more certain than min_sigma_m (1e-30 m made it outweigh every other
  // map), along any direction: a thin ellipse whose axes are each within the bound too.
  limits.min_sigma_m = 1e-3;
  m = Grid(3, 1.0, 0.1);
  m.landmarks[2].cov = 1e-60 * Eigen::Matrix2d::Identity();
  EXPECT_EQ(CheckMapLimits(m, limits), MapLimitViolation::kCovarianceTooSmall);
  m.landmarks[2].cov << 0.01, 0.01 - 1e-9, 0.01 - 1e-9, 0.01;  // sigma 0.1 m along x and y, 2e-5 m across
  EXPECT_EQ(CheckMapLimits(m, limits), MapLimitViolation::kCovarianceTooSmall);
  m.landmarks[2].cov << 0.01, 0.0099, 0.0099, 0.01;  // 7 mm across
  EXPECT_EQ(CheckMapLimits(m, limits), MapLimitViolation::kNone);
  EXPECT_EQ(ToString(MapLimitViolation::kCovarianceTooSmall), "covariance_too_small");
  EXPECT_EQ(MapLimits{}.min_sigma_m, 1e-6);
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
  // A landmark's marginal more certain than min_sigma_m (issue R3: a factor of 1e-30 I was
  // taken); the end pose is not held to it (a robot that stood still knows where it is).
  limits.max_landmarks = 2;
  WireSubmap sure = s;
  ASSERT_TRUE(sure.SetCovariance(1e-30 * Eigen::MatrixXd::Identity(7, 7)));
  EXPECT_EQ(CheckSubmapLimits(sure, limits), MapLimitViolation::kCovarianceTooSmall);
  Eigen::MatrixXd still = Eigen::MatrixXd::Identity(7, 7);
  still.topLeftCorner(3, 3) = 1e-20 * Eigen::Matrix3d::Identity();
  ASSERT_TRUE(sure.SetCovariance(still));
  EXPECT_EQ(CheckSubmapLimits(sure, limits), MapLimitViolation::kNone);
}

}  // namespace
}  // namespace mapmesh
