#include "common/metrics/agent_evaluation.h"

#include <gtest/gtest.h>

#include <map>

namespace mapmesh {
namespace {

// Robot 1's map frame truly is at a1, robot 2's at a2 (fixed at t = 5); each map is in fact
// drawn in a frame that drifted from its origin (f1, f2): what MapFrameInWorld would find.
class ScorePlacementTest : public ::testing::Test {
 protected:
  const Pose2 a1{1.0, 2.0, 0.3}, a2{-4.0, 6.0, -1.2};
  const Pose2 f1 = a1 * Pose2{0.2, -0.1, 0.02}, f2 = a2 * Pose2{-0.3, 0.4, -0.05};
  const TruePoseAt truth = [this](RobotId r, double t) -> std::optional<Pose2> {
    if (t != 5.0) return std::nullopt;
    if (r == 1) return a1;
    if (r == 2) return a2;
    return std::nullopt;
  };
  PlacedPeer Placed(const Pose2& to_own) const { return {2, 1, to_own, {3.0, -1.0}, 5.0}; }
};

TEST_F(ScorePlacementTest, TheTrueTransformBetweenOriginsHasNoStartError) {
  const auto e = ScorePlacement(Placed(a1.Inverse() * a2), a1, truth, f1, f2);
  ASSERT_TRUE(e);
  EXPECT_NEAR(e->from_start.translation_m, 0.0, 1e-12);
  EXPECT_NEAR(e->from_start.rotation_rad, 0.0, 1e-12);
  ASSERT_TRUE(e->from_fit);
  EXPECT_GT(e->from_fit->translation_m, 0.1);  // the maps' own drift is not where they are
}

TEST_F(ScorePlacementTest, TheTransformBetweenTheMapsFramesHasNoFitError) {
  const auto e = ScorePlacement(Placed(f1.Inverse() * f2), a1, truth, f1, f2);
  ASSERT_TRUE(e && e->from_fit);
  EXPECT_NEAR(e->from_fit->translation_m, 0.0, 1e-12);
  EXPECT_NEAR(e->from_fit->rotation_rad, 0.0, 1e-12);
  EXPECT_GT(e->from_start.translation_m, 0.1);
}

TEST_F(ScorePlacementTest, ErrorsAreTakenAtThePeerMapsCentroid) {
  // A rotation error about the point where the peer map's centroid lands moves nothing there.
  const Pose2 right = a1.Inverse() * a2;
  const Eigen::Vector2d c = right.Apply(Eigen::Vector2d(3.0, -1.0));
  const Pose2 about_c = Pose2{c.x(), c.y(), 0.1} * Pose2{-c.x(), -c.y(), 0.0};
  const auto e = ScorePlacement(Placed(about_c * right), a1, truth, std::nullopt, f2);
  ASSERT_TRUE(e);
  EXPECT_NEAR(e->from_start.translation_m, 0.0, 1e-12);
  EXPECT_NEAR(e->from_start.rotation_rad, 0.1, 1e-12);
  EXPECT_FALSE(e->from_fit);  // needs both fits
}

TEST_F(ScorePlacementTest, UnknownPeerOriginIsNotScored) {
  PlacedPeer p = Placed(Pose2{});
  p.origin_stamp = 4.0;
  EXPECT_FALSE(ScorePlacement(p, a1, truth, f1, f2));
  p = Placed(Pose2{});
  p.robot = 9;
  EXPECT_FALSE(ScorePlacement(p, a1, truth, f1, f2));
}

}  // namespace
}  // namespace mapmesh
