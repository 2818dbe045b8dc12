#include "common/metrics/reference_metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace mapmesh {
namespace {

LandmarkMap World(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 60.0);
  LandmarkMap m;
  while (static_cast<int>(m.size()) < n) {
    const Eigen::Vector2d p(u(rng), u(rng));
    bool spaced = true;
    for (const Landmark& l : m.landmarks) spaced = spaced && (l.mean - p).norm() > 3.0;
    if (!spaced) continue;
    Landmark l;
    l.id = static_cast<std::uint32_t>(m.size());
    l.signature = static_cast<std::int32_t>(m.size());
    l.mean = p;
    l.cov = Eigen::Matrix2d::Identity() * 0.01;
    m.landmarks.push_back(l);
  }
  return m;
}

LandmarkMap Noisy(const LandmarkMap& m, double sigma, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, sigma);
  LandmarkMap out = m;
  for (Landmark& l : out.landmarks) l.mean += Eigen::Vector2d(n(rng), n(rng));
  return out;
}

class ReferenceQualityTest : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(ReferenceQualityTest, FindsTheFrameCountsMatchesDuplicatesAndExtras) {
  std::mt19937_64 rng(GetParam());
  const LandmarkMap world = World(60, rng);
  const LandmarkMap reference = Noisy(world, 0.05, rng);
  // The map: 40 of the landmarks in its own frame, 3 of them mapped twice (0.8 m off), 2 strays.
  const Pose2 map_in_world{12.0, -5.0, 0.7};
  LandmarkMap seen;
  for (int i = 0; i < 40; ++i) seen.landmarks.push_back(world.landmarks[i]);
  seen = Noisy(seen, 0.05, rng);
  for (int i = 0; i < 3; ++i) {
    Landmark d = seen.landmarks[i];
    d.mean += Eigen::Vector2d(0.8, 0.0);
    seen.landmarks.push_back(d);
  }
  for (const Eigen::Vector2d& p : {Eigen::Vector2d(200.0, 200.0), Eigen::Vector2d(-150.0, 90.0)}) {
    Landmark s;
    s.mean = p;
    s.cov = Eigen::Matrix2d::Identity() * 0.01;
    seen.landmarks.push_back(s);
  }
  const LandmarkMap map = TransformMap(seen, map_in_world.Inverse());

  const ReferenceQuality q = CompareToReference(map, reference, 2.0, AlignmentOptions{}, rng);
  ASSERT_TRUE(q.aligned);
  EXPECT_NEAR(q.to_reference.x, map_in_world.x, 0.1);
  EXPECT_NEAR(q.to_reference.y, map_in_world.y, 0.1);
  EXPECT_NEAR(q.to_reference.theta, map_in_world.theta, 0.01);
  EXPECT_EQ(q.landmarks, 45);
  EXPECT_EQ(q.reference_landmarks, 60);
  EXPECT_EQ(q.matched, 40);
  EXPECT_EQ(q.duplicates, 3);
  EXPECT_EQ(q.extra, 2);
  EXPECT_DOUBLE_EQ(q.reference_coverage, 40.0 / 60.0);
  // Both maps carry 0.05 m per axis: about 0.1 m apart, and NEES near 2 with both covariances
  // (0.01 each, so 0.02 against a true 0.005 per axis: NEES about 0.5).
  EXPECT_GT(q.rmse_m, 0.04);
  EXPECT_LT(q.rmse_m, 0.16);
  EXPECT_GT(q.nees_mean, 0.2);
  EXPECT_LT(q.nees_mean, 1.0);
}

INSTANTIATE_TEST_SUITE_P(Seeds, ReferenceQualityTest, ::testing::Range<std::uint64_t>(1, 6));

TEST(ReferenceQuality, AKnownFrameSkipsTheAlignment) {
  std::mt19937_64 rng(2);
  const LandmarkMap reference = World(50, rng);
  const Pose2 frame{3.0, 4.0, -0.5};
  const LandmarkMap map = TransformMap(reference, frame.Inverse());
  const ReferenceQuality q = CompareToReference(map, reference, 2.0, AlignmentOptions{}, rng, frame);
  ASSERT_TRUE(q.aligned);
  EXPECT_EQ(q.to_reference.x, frame.x);
  EXPECT_EQ(q.matched, 50);
  EXPECT_LT(q.rmse_m, 1e-9);
  // A wrong known frame is used as given: nothing matches.
  const ReferenceQuality off = CompareToReference(map, reference, 2.0, AlignmentOptions{}, rng, Pose2{500.0, 0.0, 0.0});
  EXPECT_TRUE(off.aligned);
  EXPECT_EQ(off.matched, 0);
  EXPECT_EQ(off.extra, 50);
}

TEST(ReferenceQuality, AnUnrelatedMapDoesNotAlign) {
  std::mt19937_64 rng(3);
  const LandmarkMap reference = World(50, rng);
  const LandmarkMap other = World(50, rng);
  const ReferenceQuality q = CompareToReference(other, reference, 2.0, AlignmentOptions{}, rng);
  EXPECT_FALSE(q.aligned);
  EXPECT_EQ(q.matched, 0);
  EXPECT_EQ(q.landmarks, 50);
}

}  // namespace
}  // namespace mapmesh
