#include "common/slam/local_slam.h"

#include <gtest/gtest.h>

#include "common/slam/observation_model.h"
#include "sim_feeder/simulator.h"
#include "tests/testing/filter_noise.h"

namespace mapmesh {
namespace {

FilterNoise Noise() { return testing::TestFilterNoise(); }

// The options these tests were written with: known association, no range limit, a 12 m CEKF
// reach, the standard EKF's Jacobians.
LocalSlamOptions Options() {
  LocalSlamOptions o;
  o.association.method = AssociationMethod::kKnown;
  o.cekf.reach_m = 12.0;
  o.ekf.first_estimates_jacobians = false;
  return o;
}

Observation See(const Eigen::Vector2d& m, std::int32_t sig, const Pose2& robot = {0, 0, 0}) {
  const Eigen::Vector2d z = ObserveRangeBearing(robot, m);
  return {z(0), z(1), sig, ObservationKind::kLandmark};
}

TEST(LocalSlam, KnownAssociationInitialisesThenFuses) {
  LocalSlam slam(Noise(), Options());
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
  LocalSlamOptions o = Options();
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
  LocalSlamOptions o = Options();
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
  LocalSlamOptions o = Options();
  o.association.method = AssociationMethod::kIcnn;
  LocalSlam slam(Noise(), o);
  slam.Observe({See({5, 1}, -1), See({5.1, 1.05}, -1), See({5, -3}, -1)}, 0.0);
  EXPECT_EQ(slam.size(), 2u);
}

TEST(LocalSlam, OutliersWithKnownSignaturesDoNotMoveTheMap) {
  LocalSlam slam(Noise(), Options());
  for (int k = 0; k < 5; ++k) slam.Observe({See({5, 0}, 1)}, k);
  const Eigen::Vector2d before = slam.Map().landmarks[0].mean;
  Observation bad = See({5, 0}, 1);
  bad.range += 2.5;
  slam.Observe({bad}, 6.0);
  EXPECT_EQ(slam.stats().rejected_gate, 1u);
  EXPECT_EQ(slam.Map().landmarks[0].mean, before);
}

TEST(LocalSlam, FirstEstimatesJacobiansReachEitherFilter) {
  const Scenario sc = ParseScenario(R"(
seed: 3
duration_s: 60
world: {landmarks: {generator: {count: 80, area_m: [0, 0, 40, 40], min_spacing_m: 1.5}}}
robots:
  count: 1
  defaults: {preset: thesis, path: {type: random, count: 4}, sensor: {signatures: true}}
)",
                                    "fej.yaml");
  auto run = [&](SlamMethod filter, bool fej) {
    LocalSlamOptions o = Options();
    o.filter = filter;
    o.cekf = {/*region_half_m=*/3.0, /*reach_m=*/9.0};
    o.ekf.first_estimates_jacobians = fej;
    LocalSlam slam(Noise(), o);
    Simulator sim(sc, BuildWorld(sc));
    while (!sim.Done()) {
      const FeedBatch b = sim.Next();
      for (const Odometry& od : b.odom) slam.Predict({od.v, od.w, 0.0}, od.dt);
      for (const Scan& scan : b.scans) slam.Observe(scan.obs, scan.stamp);
    }
    EXPECT_GT(slam.stats().associated, 100u);
    return slam.Map();
  };
  auto largest_difference = [](const LandmarkMap& a, const LandmarkMap& b) {
    EXPECT_EQ(a.size(), b.size());
    double d = 0.0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
      d = std::max(d, (a.landmarks[i].mean - b.landmarks[i].mean).cwiseAbs().maxCoeff());
    }
    return d;
  };
  const LandmarkMap ekf = run(SlamMethod::kEkf, false), cekf = run(SlamMethod::kCekf, false);
  const LandmarkMap ekf_fej = run(SlamMethod::kEkf, true), cekf_fej = run(SlamMethod::kCekf, true);
  EXPECT_LT(largest_difference(ekf, cekf), 1e-9);
  EXPECT_LT(largest_difference(ekf_fej, cekf_fej), 1e-9);
  EXPECT_GT(largest_difference(ekf, ekf_fej), 1e-6);  // the option reached the filters
}

}  // namespace
}  // namespace mapmesh
