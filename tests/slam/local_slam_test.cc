#include "common/slam/local_slam.h"

#include <gtest/gtest.h>

#include "common/slam/observation_model.h"

namespace mapmesh {
namespace {

FilterNoise Noise() {
  FilterNoise n;
  n.control_cov = Eigen::Vector2d(0.03 * 0.03, 0.05 * 0.05).asDiagonal();
  n.obs_cov = Eigen::Vector2d(0.05 * 0.05, std::pow(DegToRad(1.0), 2)).asDiagonal();
  return n;
}

Observation See(const Eigen::Vector2d& m, std::int32_t sig, const Pose2& robot = {0, 0, 0}) {
  const Eigen::Vector2d z = ObserveRangeBearing(robot, m);
  return {z(0), z(1), sig, ObservationKind::kLandmark};
}

TEST(LocalSlam, KnownAssociationInitialisesThenFuses) {
  LocalSlam slam(Noise(), {});
  slam.Observe({See({4, 1}, 3), See({6, -2}, 8), {2.0, 0.1, 5, ObservationKind::kRobot}}, 0.0);
  EXPECT_EQ(slam.size(), 2u);
  EXPECT_EQ(slam.stats().initialised, 2u);
  EXPECT_EQ(slam.last_decisions()[2].landmark, LocalSlam::kNotLandmark);
  EXPECT_TRUE(slam.last_decisions()[0].initialised);
  slam.Observe({See({4, 1}, 3)}, 0.5);
  EXPECT_EQ(slam.stats().associated, 1u);
  EXPECT_EQ(slam.last_decisions()[0].landmark, 3);
  const LandmarkMap m = slam.Map();
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m.landmarks[0].id, 3u);
  EXPECT_EQ(m.landmarks[0].signature, 3);
  EXPECT_NEAR((m.landmarks[0].mean - Eigen::Vector2d(4, 1)).norm(), 0.0, 1e-9);
}

TEST(LocalSlam, DropsInvalidAndOutOfRangeObservationsWithCounts) {
  LocalSlamOptions o;
  o.max_range_m = 10.0;
  LocalSlam slam(Noise(), o);
  slam.Observe({{std::nan(""), 0.1, 1, ObservationKind::kLandmark},
                {-1.0, 0.1, 2, ObservationKind::kLandmark},
                {3.0, std::numeric_limits<double>::infinity(), 3, ObservationKind::kLandmark},
                {12.0, 0.1, 4, ObservationKind::kLandmark},
                See({3, 0}, 5)},
               0.0);
  EXPECT_EQ(slam.stats().invalid, 3u);
  EXPECT_EQ(slam.stats().out_of_range, 1u);
  EXPECT_EQ(slam.size(), 1u);
}

TEST(LocalSlam, TentativeLandmarksNeedASecondSighting) {
  LocalSlamOptions o;
  o.tentative = true;
  o.tentative_timeout_s = 5.0;
  o.association.method = AssociationMethod::kJcbb;
  LocalSlam slam(Noise(), o);
  slam.Observe({See({4, 1}, -1)}, 0.0);
  EXPECT_EQ(slam.size(), 0u);
  EXPECT_EQ(slam.last_decisions()[0].landmark, LocalSlam::kHeld);
  slam.Observe({See({4.05, 1}, -1), See({8, -3}, -1)}, 1.0);  // the first again, and a new one
  EXPECT_EQ(slam.size(), 1u);
  EXPECT_TRUE(slam.last_decisions()[0].initialised);
  slam.Observe({See({8, -3}, -1)}, 10.0);  // too late: the first sighting was forgotten
  EXPECT_EQ(slam.size(), 1u);
  EXPECT_EQ(slam.stats().tentative, 3u);
}

TEST(LocalSlam, OneScanSeeingANewTreeTwiceMakesOneLandmark) {
  LocalSlamOptions o;
  o.association.method = AssociationMethod::kIcnn;
  LocalSlam slam(Noise(), o);
  slam.Observe({See({5, 1}, -1), See({5.1, 1.05}, -1), See({5, -3}, -1)}, 0.0);
  EXPECT_EQ(slam.size(), 2u);
}

TEST(LocalSlam, OutliersWithKnownSignaturesDoNotMoveTheMap) {
  LocalSlam slam(Noise(), {});
  for (int k = 0; k < 5; ++k) slam.Observe({See({5, 0}, 1)}, k);
  const Eigen::Vector2d before = slam.Map().landmarks[0].mean;
  Observation bad = See({5, 0}, 1);
  bad.range += 2.5;
  slam.Observe({bad}, 6.0);
  EXPECT_EQ(slam.stats().rejected_gate, 1u);
  EXPECT_EQ(slam.Map().landmarks[0].mean, before);
}

}  // namespace
}  // namespace mapmesh
