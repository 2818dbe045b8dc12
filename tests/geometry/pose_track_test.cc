#include "common/geometry/pose_track.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mapmesh {
namespace {

struct Sample {
  double t;
  Pose2 pose;
};

std::optional<Pose2> At(const std::vector<Sample>& track, double t) {
  return PoseAlong(
      track, t, [](const Sample& s) { return s.t; }, [](const Sample& s) { return s.pose; });
}

TEST(PoseAlong, EmptyTrackHasNoPose) { EXPECT_FALSE(At({}, 1.0)); }

TEST(PoseAlong, ClampsToTheEndsAndReturnsSamplesExactly) {
  const std::vector<Sample> track = {{1.0, {0.1, 0.2, 0.3}}, {2.0, {1.0 / 3.0, 0.7, -3.1}}, {3.0, {2.0, 1.0, 3.1}}};
  for (double t : {-5.0, 1.0}) EXPECT_EQ(At(track, t)->x, 0.1);
  for (double t : {3.0, 1e9}) EXPECT_EQ(At(track, t)->theta, 3.1);
  const Pose2 mid = *At(track, 2.0);  // bit for bit the sample, not an interpolation ending there
  EXPECT_EQ(mid.x, 1.0 / 3.0);
  EXPECT_EQ(mid.theta, -3.1);
}

TEST(PoseAlong, InterpolatesPositionLinearlyAndHeadingAlongTheShorterArc) {
  const std::vector<Sample> track = {{0.0, {0.0, 0.0, 3.0}}, {2.0, {4.0, -2.0, -3.0}}};
  const Pose2 p = *At(track, 0.5);
  EXPECT_DOUBLE_EQ(p.x, 1.0);
  EXPECT_DOUBLE_EQ(p.y, -0.5);
  // From 3 to -3 rad the short way crosses pi: a quarter of 2*pi - 6 beyond 3.
  EXPECT_NEAR(p.theta, 3.0 + 0.25 * (2 * M_PI - 6.0), 1e-12);
}

TEST(PoseAlong, AgreesWithInterpolateBetweenTheSamplesAroundAnyTime) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-3.0, 3.0), dt(0.01, 1.0);
  std::vector<Sample> track;
  double t = 0.0;
  for (int i = 0; i < 50; ++i) {
    track.push_back({t, {u(rng), u(rng), u(rng)}});
    t += dt(rng);
  }
  for (int k = 0; k < 200; ++k) {
    const double q = std::uniform_real_distribution<double>(0.0, track.back().t)(rng);
    std::size_t i = 1;
    while (track[i].t < q) ++i;
    const Pose2 want = Interpolate(track[i - 1].pose, track[i].pose,
                                   (q - track[i - 1].t) / (track[i].t - track[i - 1].t));
    const Pose2 got = *At(track, q);
    EXPECT_EQ(got.x, want.x);
    EXPECT_EQ(got.y, want.y);
    EXPECT_EQ(got.theta, want.theta);
  }
}

}  // namespace
}  // namespace mapmesh
