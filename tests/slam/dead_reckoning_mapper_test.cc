#include "common/slam/dead_reckoning_mapper.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

Observation Obs(double r, double b, int sig) { return {r, b, sig, ObservationKind::kLandmark}; }

TEST(DeadReckoningMapper, NoiselessObservationsLandOnTheLandmark) {
  DeadReckoningMapper m({});
  // Drive 1 m straight ahead, then see a landmark at (3, 4) in the start frame.
  for (int i = 0; i < 10; ++i) m.Predict({1.0, 0.0, 0.0}, 0.1);
  EXPECT_NEAR(m.pose().x, 1.0, 1e-12);
  const Eigen::Vector2d lm(3.0, 4.0);
  const Eigen::Vector2d d = lm - Eigen::Vector2d(1.0, 0.0);
  m.Observe({Obs(d.norm(), std::atan2(d.y(), d.x()), 5)});
  m.Observe({Obs(d.norm(), std::atan2(d.y(), d.x()), 5)});
  const LandmarkMap map = m.Map();
  ASSERT_EQ(map.size(), 1u);
  EXPECT_EQ(map.landmarks[0].signature, 5);
  EXPECT_EQ(map.landmarks[0].id, 5u);
  EXPECT_NEAR((map.landmarks[0].mean - lm).norm(), 0.0, 1e-12);
  EXPECT_TRUE(IsValidCovariance(map.landmarks[0].cov));
}

TEST(DeadReckoningMapper, AveragingShrinksCovariance) {
  DeadReckoningMapper m({});
  m.Observe({Obs(5.0, 0.0, 1)});
  const double one = m.Map().landmarks[0].cov.trace();
  for (int i = 0; i < 9; ++i) m.Observe({Obs(5.0, 0.0, 1)});
  EXPECT_NEAR(m.Map().landmarks[0].cov.trace(), one / 10.0, 1e-12);
}

TEST(DeadReckoningMapper, WithoutSignaturesJoinsTheNearestWithinTheGate) {
  DeadReckoningOptions o;
  o.association_gate_m = 0.5;
  DeadReckoningMapper m(o);
  m.Observe({Obs(5.0, 0.0, -1), Obs(5.0, 0.5, -1)});  // two landmarks ~2.5 m apart
  m.Observe({Obs(5.2, 0.0, -1)});                     // 0.2 m from the first
  const LandmarkMap map = m.Map();
  ASSERT_EQ(map.size(), 2u);
  EXPECT_NEAR(map.landmarks[0].mean.x(), 5.1, 1e-12);
}

TEST(DeadReckoningMapper, IgnoresRobotSightings) {
  DeadReckoningMapper m({});
  m.Observe({{3.0, 0.1, 2, ObservationKind::kRobot}});
  EXPECT_EQ(m.size(), 0u);
}

}  // namespace
}  // namespace mapmesh
