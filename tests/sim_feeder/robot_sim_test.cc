#include "sim_feeder/robot_sim.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

SensorOptions Lms200() { return SensorOptions{}; }  // 8 m, 180 deg

TEST(IsVisible, BoundingBoxRejectsFarCoordinates) {
  // Thesis Fig. 32: a landmark outside the square of half-side max_range is rejected.
  EXPECT_FALSE(IsVisible({0, 0, 0}, {8.5, 0.0}, Lms200()));
  EXPECT_FALSE(IsVisible({0, 0, 0}, {1.0, -8.1}, Lms200()));
}

TEST(IsVisible, BoundingLineRejectsLandmarksBehind) {
  // Thesis Fig. 33: inside the box but behind the robot.
  EXPECT_FALSE(IsVisible({0, 0, 0}, {-1.0, 2.0}, Lms200()));
  EXPECT_TRUE(IsVisible({0, 0, 0}, {1.0, 2.0}, Lms200()));
  // Heading north: "in front" follows the heading.
  EXPECT_FALSE(IsVisible({0, 0, M_PI / 2}, {1.0, -2.0}, Lms200()));
  EXPECT_TRUE(IsVisible({0, 0, M_PI / 2}, {1.0, 2.0}, Lms200()));
}

TEST(IsVisible, BoundingCircleRejectsTheBoxCorners) {
  // Thesis Fig. 34: in the box and in front, but beyond the range circle.
  EXPECT_FALSE(IsVisible({0, 0, 0}, {6.0, 6.0}, Lms200()));
  EXPECT_TRUE(IsVisible({0, 0, 0}, {5.0, 5.0}, Lms200()));
  EXPECT_TRUE(IsVisible({2, 3, 0}, {10.0, 3.0}, Lms200()));  // exactly at range
}

TEST(IsVisible, NarrowFieldOfView) {
  SensorOptions s;
  s.fov_deg = 90;
  EXPECT_TRUE(IsVisible({0, 0, 0}, {3.0, 2.9}, s));
  EXPECT_FALSE(IsVisible({0, 0, 0}, {3.0, 3.1}, s));
  s.fov_deg = 360;
  EXPECT_TRUE(IsVisible({0, 0, 0}, {-3.0, 0.0}, s));
}

TEST(RangeBearing, FollowsEq100) {
  const Observation o = RangeBearing({1, 1, M_PI / 2}, {4, 5});
  EXPECT_NEAR(o.range, 5.0, 1e-12);
  EXPECT_NEAR(o.bearing, std::atan2(4.0, 3.0) - M_PI / 2, 1e-12);
}

TEST(SenseLandmarks, NoiseHasTheConfiguredMeanAndSpread) {
  SensorOptions s;
  s.signatures = true;
  std::mt19937_64 rng(17);
  const std::vector<Eigen::Vector2d> lms{{4.0, 1.0}};
  const Observation truth = RangeBearing({0, 0, 0}, lms[0]);
  const int kN = 20000;
  double sr = 0, sb = 0, sr2 = 0, sb2 = 0;
  for (int i = 0; i < kN; ++i) {
    const auto obs = SenseLandmarks({0, 0, 0}, lms, s, rng);
    ASSERT_EQ(obs.size(), 1u);
    ASSERT_EQ(obs[0].signature, 0);
    const double dr = obs[0].range - truth.range, db = WrapAngle(obs[0].bearing - truth.bearing);
    sr += dr;
    sb += db;
    sr2 += dr * dr;
    sb2 += db * db;
  }
  const double sigma_b = DegToRad(s.sigma_bearing_deg);
  // Means within 4 standard errors, variances within 4 % (sd of a sample variance ~ sqrt(2/N)).
  EXPECT_NEAR(sr / kN, 0.0, 4 * s.sigma_range_m / std::sqrt(kN));
  EXPECT_NEAR(sb / kN, 0.0, 4 * sigma_b / std::sqrt(kN));
  EXPECT_NEAR(sr2 / kN / (s.sigma_range_m * s.sigma_range_m), 1.0, 0.04);
  EXPECT_NEAR(sb2 / kN / (sigma_b * sigma_b), 1.0, 0.04);
}

TEST(SenseLandmarks, NoSignaturesUnlessShared) {
  std::mt19937_64 rng(1);
  std::vector<int> idx;
  const auto obs = SenseLandmarks({0, 0, 0}, {{-3, 0}, {3, 0}}, SensorOptions{}, rng, &idx);
  ASSERT_EQ(obs.size(), 1u);
  EXPECT_EQ(obs[0].signature, -1);
  EXPECT_EQ(idx, std::vector<int>{1});
}

TEST(FollowWaypoints, ThesisSteeringIsFullRateOrNothingAtConstantSpeed) {
  PathOptions path;
  path.type = PathType::kWaypoints;
  path.points = {{0.0, 10.0}};
  MotionOptions m;  // thesis defaults
  FollowerState st;
  // Waypoint 90 deg to the left: full rate (30 deg/s), speed unchanged.
  UnicycleControl u = FollowWaypoints({0, 0, 0}, path, m, 0.1, st);
  EXPECT_NEAR(u.w_radps, DegToRad(30), 1e-12);
  EXPECT_DOUBLE_EQ(u.v_mps, 0.3);
  // To the right, and behind: full rate the other way, still driving.
  u = FollowWaypoints({0, 0, M_PI - 0.1}, path, m, 0.1, st);
  EXPECT_NEAR(u.w_radps, -DegToRad(30), 1e-12);
  u = FollowWaypoints({0, 0, -M_PI / 2}, path, m, 0.1, st);
  EXPECT_DOUBLE_EQ(u.v_mps, 0.3);
  // Within one step's turn (3 deg) of the bearing: no turn (Fig. 27).
  u = FollowWaypoints({0, 0, M_PI / 2 - DegToRad(2.5)}, path, m, 0.1, st);
  EXPECT_DOUBLE_EQ(u.w_radps, 0.0);
}

TEST(FollowWaypoints, SmoothSteeringClosesTheErrorAndTurnsInPlace) {
  PathOptions path;
  path.type = PathType::kWaypoints;
  path.points = {{0.0, 10.0}};
  MotionOptions m;
  m.steering = Steering::kSmooth;
  FollowerState st;
  UnicycleControl u = FollowWaypoints({0, 0, 0}, path, m, 0.1, st);
  EXPECT_NEAR(u.w_radps, DegToRad(30), 1e-12);
  EXPECT_DOUBLE_EQ(u.v_mps, 0.3);
  u = FollowWaypoints({0, 0, M_PI / 2 - 0.01}, path, m, 0.1, st);
  EXPECT_NEAR(u.w_radps, 0.1, 1e-9);
  u = FollowWaypoints({0, 0, -M_PI / 2}, path, m, 0.1, st);
  EXPECT_DOUBLE_EQ(u.v_mps, 0.0);
}

TEST(FollowWaypoints, SwitchesInsideTheRadiusAndLoops) {
  PathOptions path;
  path.type = PathType::kWaypoints;
  path.points = {{1.0, 0.0}, {5.0, 0.0}};
  MotionOptions m;
  FollowerState st;
  FollowWaypoints({0.7, 0.0, 0}, path, m, 0.1, st);
  EXPECT_EQ(st.next, 1u);
  FollowWaypoints({4.8, 0.0, 0}, path, m, 0.1, st);
  EXPECT_EQ(st.next, 0u);  // loops back
  path.loop = false;
  st = {};
  st.next = 1;
  const UnicycleControl u = FollowWaypoints({4.8, 0.0, 0}, path, m, 0.1, st);
  EXPECT_TRUE(st.finished);
  EXPECT_DOUBLE_EQ(u.v_mps, 0.0);
}

TEST(FollowWaypoints, ARobotReachesEveryWaypointWithEitherSteering) {
  for (const Steering steering : {Steering::kThesis, Steering::kSmooth}) {
    SCOPED_TRACE(NameOf(kSteerings, steering));
    PathOptions path;
    path.type = PathType::kWaypoints;
    path.points = {{10, 0}, {10, 10}, {0, 10}, {0, 0}};
    path.loop = false;
    MotionOptions m;
    m.steering = steering;
    FollowerState st;
    Pose2 p{0, 0, M_PI};
    for (int k = 0; k < 3000 && !st.finished; ++k) {
      p = UnicycleMotion(p, FollowWaypoints(p, path, m, 0.1, st), 0.1);
    }
    EXPECT_TRUE(st.finished);
    EXPECT_LT(std::hypot(p.x, p.y), m.waypoint_radius_m + 0.05);
  }
}

}  // namespace
}  // namespace mapmesh
