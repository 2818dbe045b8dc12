#include "common/metrics/trajectory_metrics.h"

#include <gtest/gtest.h>

#include "common/geometry/pose2.h"

namespace mapmesh {
namespace {

TEST(CompareTrajectory, InterpolatesTheEstimateAtReferenceTimes) {
  const std::vector<TimedPosition> est{{0, {0, 0}}, {1, {1, 0}}, {2, {2, 0}}, {10, {10, 0}}};
  const std::vector<TimedPosition> ref{{0.5, {0.5, 0.3}}, {1.5, {1.5, -0.3}}, {5, {5, 0}}, {20, {20, 0}}};
  const TrajectoryError e = CompareTrajectory(est, ref, /*align=*/false, /*max_gap_s=*/1.0);
  // t = 5 lies in an 8 s gap of the estimate, t = 20 after it: both skipped.
  ASSERT_EQ(e.samples, 2);
  EXPECT_NEAR(e.rmse_m, 0.3, 1e-12);
}

TEST(CompareTrajectory, AlignmentRemovesAnUnknownFrame) {
  const Pose2 frame{5, -3, 0.8};
  std::vector<TimedPosition> est, ref;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector2d p(0.5 * i, std::sin(0.2 * i) * 3);
    est.push_back({0.1 * i, p});
    ref.push_back({0.1 * i, frame.Apply(p)});
  }
  EXPECT_GT(CompareTrajectory(est, ref, false).rmse_m, 1.0);
  const TrajectoryError e = CompareTrajectory(est, ref, true);
  EXPECT_TRUE(e.aligned);
  EXPECT_NEAR(e.rmse_m, 0.0, 1e-9);
}

TEST(DropImplausibleFixes, RemovesJumps) {
  const std::vector<TimedPosition> fixes{{0, {0, 0}}, {1, {2, 0}}, {2, {140, 0}}, {3, {6, 0}}};
  const auto kept = DropImplausibleFixes(fixes, 20.0);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[2].t, 3);
}

}  // namespace
}  // namespace mapmesh
