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

// A wiggly reference track sampled every 0.125 s (times exact in binary).
std::vector<PoseStamp> WigglyTrack(int n) {
  std::vector<PoseStamp> track;
  Pose2 pose;
  for (int i = 0; i < n; ++i) {
    track.push_back({0.125 * i, pose});
    pose = pose * Pose2{0.05, 0.0, 0.1 * std::sin(0.05 * i)};
  }
  return track;
}

TEST(CompareRelativePoses, AnyFrameGivesZeroAndAConstantErrorPerStepIsFound) {
  const std::vector<PoseStamp> ref = WigglyTrack(200);
  // The same motion in another frame: no relative error.
  std::vector<PoseStamp> moved;
  const Pose2 frame{5, -3, 0.8};
  for (const PoseStamp& s : ref) moved.push_back({s.t, frame * s.pose});
  const RelativeTrajectoryError same = CompareRelativePoses(moved, ref, 1.0);
  EXPECT_GT(same.pairs, 150);
  EXPECT_NEAR(same.translation_rmse_m, 0.0, 1e-9);
  EXPECT_NEAR(same.rotation_rmse_rad, 0.0, 1e-9);
  // Every step of the estimate turns 0.002 rad more: over 1 s (8 steps) the relative heading
  // error is 0.016 rad on every pair, whatever the absolute error has grown to.
  std::vector<PoseStamp> est;
  Pose2 pose;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    est.push_back({ref[i].t, pose});
    if (i + 1 < ref.size()) pose = pose * (ref[i].pose.Inverse() * ref[i + 1].pose) * Pose2{0, 0, 0.002};
  }
  const RelativeTrajectoryError drift = CompareRelativePoses(est, ref, 1.0);
  EXPECT_EQ(drift.pairs, 200 - 8);
  EXPECT_NEAR(drift.rotation_rmse_rad, 0.016, 1e-9);
  EXPECT_GT(drift.translation_rmse_m, 0.0);
  EXPECT_LT(drift.translation_rmse_m, 0.05 * 8 * 0.016);  // at most the span's length times the turn
}

TEST(CompareRelativePoses, SkipsSpansTheEstimateDoesNotCover) {
  const std::vector<PoseStamp> ref = WigglyTrack(100);  // 0-12.375 s
  std::vector<PoseStamp> est;
  for (const PoseStamp& s : ref) {
    if (s.t <= 3.0 || s.t >= 6.0) est.push_back(s);  // a 3 s gap
  }
  const RelativeTrajectoryError e = CompareRelativePoses(est, ref, 1.0, 0.5);
  // Pairs starting at 0-2 s and 6-11.375 s: 17 + 44, none reaching into the gap.
  EXPECT_EQ(e.pairs, 17 + 44);
  EXPECT_NEAR(e.translation_rmse_m, 0.0, 1e-12);
  EXPECT_EQ(CompareRelativePoses({}, ref, 1.0).pairs, 0);
  EXPECT_EQ(CompareRelativePoses(ref, ref, 100.0).pairs, 0);  // no span that long
}

TEST(DropImplausibleFixes, RemovesJumps) {
  const std::vector<TimedPosition> fixes{{0, {0, 0}}, {1, {2, 0}}, {2, {140, 0}}, {3, {6, 0}}};
  const auto kept = DropImplausibleFixes(fixes, 20.0);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[2].t, 3);
}

}  // namespace
}  // namespace mapmesh
