#include "common/merge/transform_search.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <string>

#include "common/metrics/trajectory_metrics.h"

namespace mapmesh {
namespace {

// Two maps cut from one seeded random world (uniform landmarks at least 1 m apart): A holds
// the square [0, side]^2, B the square shifted along the diagonal so that the two share
// `overlap` of their area (overlap 0: set two sides apart), B's landmarks seen in the frame
// truth^-1 and shuffled, both with independent noise sigma.
struct Planted {
  LandmarkMap a, b;
  Pose2 truth;  // maps B's frame into A's
  std::set<std::pair<int, int>> true_pairs;
};

Planted MakePlanted(std::uint64_t seed, int n, double overlap, double sigma) {
  std::mt19937_64 rng(seed);
  const double density = 0.08, side = std::sqrt(n / density);
  const double shift = overlap > 0 ? (1.0 - std::sqrt(overlap)) * side : 2.0 * side;
  std::uniform_real_distribution<double> u(0.0, side + shift);
  std::vector<Eigen::Vector2d> world;
  const int count = static_cast<int>(density * (side + shift) * (side + shift));
  for (int tries = 0; static_cast<int>(world.size()) < count && tries < 100 * count; ++tries) {
    const Eigen::Vector2d p(u(rng), u(rng));
    bool apart = true;
    for (const Eigen::Vector2d& q : world) apart = apart && (p - q).norm() >= 1.0;
    if (apart) world.push_back(p);
  }
  Planted out;
  std::uniform_real_distribution<double> ut(-100.0, 100.0), ua(-M_PI, M_PI);
  out.truth = Pose2{ut(rng), ut(rng), ua(rng)};
  const Pose2 to_b = out.truth.Inverse();
  std::normal_distribution<double> noise(0.0, sigma);
  const Eigen::Matrix2d cov = std::max(sigma, 0.01) * std::max(sigma, 0.01) * Eigen::Matrix2d::Identity();
  std::vector<int> a_of(world.size(), -1), in_b;
  for (std::size_t w = 0; w < world.size(); ++w) {
    const Eigen::Vector2d& p = world[w];
    if (p.x() <= side && p.y() <= side) {
      a_of[w] = static_cast<int>(out.a.size());
      out.a.landmarks.push_back({static_cast<std::uint32_t>(out.a.size()), -1,
                                 p + Eigen::Vector2d(noise(rng), noise(rng)), cov});
    }
    if (p.x() >= shift && p.y() >= shift) in_b.push_back(static_cast<int>(w));
  }
  std::shuffle(in_b.begin(), in_b.end(), rng);
  for (int w : in_b) {
    const int ib = static_cast<int>(out.b.size());
    out.b.landmarks.push_back({static_cast<std::uint32_t>(ib), -1,
                               to_b.Apply(world[w] + Eigen::Vector2d(noise(rng), noise(rng))), cov});
    if (a_of[w] >= 0) out.true_pairs.emplace(a_of[w], ib);
  }
  return out;
}

AlignmentOptions WithSearch(TransformSearch search) {
  AlignmentOptions o;
  o.search = search;
  return o;
}

std::string Name(TransformSearch s) { return std::string(NameOf(kTransformSearch, s)); }

class SearchTest : public ::testing::TestWithParam<std::tuple<TransformSearch, int>> {};

// A planted transform is recovered, by the search's own inliers: accepted, within 0.1 m at B's
// centroid and 0.5 degrees, nearly every inlier a true pair and most true pairs found.
TEST_P(SearchTest, RecoversAPlantedTransform) {
  const auto [search, seed] = GetParam();
  const Planted p = MakePlanted(seed, 200, 0.4, 0.05);
  ASSERT_GE(p.true_pairs.size(), 50u);
  std::mt19937_64 rng(seed);
  const AlignmentResult r = AlignMaps(p.a, p.b, WithSearch(search), rng);
  ASSERT_TRUE(r.accepted()) << Name(search) << ": " << ToString(r.verdict);
  const TransformError e = CompareTransforms(r.transform, p.truth, Centroid(p.b));
  EXPECT_LT(e.translation_m, 0.1);
  EXPECT_LT(RadToDeg(e.rotation_rad), 0.5);
  int good = 0;
  for (const auto& q : r.inliers) good += p.true_pairs.count(q);
  EXPECT_GE(good, 0.95 * r.inliers.size());
  EXPECT_GE(static_cast<double>(r.inliers.size()), 0.8 * p.true_pairs.size());
  // The best hypothesis is not ambiguous: a different one has far less support.
  EXPECT_LT(r.runner_up_support, 0.7 * r.best_support);
}

// Maps that share no landmark are not accepted, whatever the search makes of them.
TEST_P(SearchTest, RefusesMapsWithoutOverlap) {
  const auto [search, seed] = GetParam();
  const Planted p = MakePlanted(100 + seed, 200, 0.0, 0.05);
  ASSERT_TRUE(p.true_pairs.empty());
  std::mt19937_64 rng(seed);
  const AlignmentResult r = AlignMaps(p.a, p.b, WithSearch(search), rng);
  EXPECT_FALSE(r.accepted()) << Name(search) << ": " << r.inliers.size() << " inliers";
}

// One seed, one answer: the same transform and inliers from a fresh generator with that seed.
TEST_P(SearchTest, IsDeterministicForASeed) {
  const auto [search, seed] = GetParam();
  const Planted p = MakePlanted(seed, 150, 0.5, 0.1);
  std::mt19937_64 rng1(seed), rng2(seed);
  const AlignmentResult r1 = AlignMaps(p.a, p.b, WithSearch(search), rng1);
  const AlignmentResult r2 = AlignMaps(p.a, p.b, WithSearch(search), rng2);
  EXPECT_EQ(r1.verdict, r2.verdict);
  EXPECT_EQ(r1.transform.x, r2.transform.x);
  EXPECT_EQ(r1.transform.y, r2.transform.y);
  EXPECT_EQ(r1.transform.theta, r2.transform.theta);
  EXPECT_EQ(r1.inliers, r2.inliers);
  EXPECT_EQ(r1.iterations, r2.iterations);
}

INSTANTIATE_TEST_SUITE_P(
    Seeds, SearchTest,
    ::testing::Combine(::testing::Values(TransformSearch::kAdaptiveRandomWalk, TransformSearch::kIterativeTranslation),
                       ::testing::Range(1, 6)),
    [](const auto& info) { return Name(std::get<0>(info.param)) + "_" + std::to_string(std::get<1>(info.param)); });

// The random walk spends exactly its budget, and a budget too small to leave the start
// (one step from a random rotation) rarely finds the planted transform that the full one does.
TEST(TransformSearch, RandomWalkSpendsItsBudgetAndNeedsIt) {
  int found_small = 0, found_full = 0;
  for (int seed = 1; seed <= 6; ++seed) {
    const Planted p = MakePlanted(seed, 200, 0.4, 0.05);
    AlignmentOptions o = WithSearch(TransformSearch::kAdaptiveRandomWalk);
    std::mt19937_64 rng(seed);
    const AlignmentResult full = AlignMaps(p.a, p.b, o, rng);
    EXPECT_EQ(full.iterations, o.arw.steps);
    found_full += full.accepted();
    o.arw.steps = 1;
    o.arw.steps_per_restart = 1;
    std::mt19937_64 rng2(seed);
    const AlignmentResult small = AlignMaps(p.a, p.b, o, rng2);
    EXPECT_EQ(small.iterations, 1);
    found_small += small.accepted();
  }
  EXPECT_EQ(found_full, 6);
  EXPECT_LE(found_small, 2);
}

// Delta counts B's landmarks that land on A's: at the truth of noise-free maps every shared
// landmark adds 1, and moving B by 5 m leaves little of it.
TEST(TransformSearch, OverlapHeuristicPeaksAtTheTruth) {
  const Planted p = MakePlanted(7, 200, 0.5, 0.0);
  const AlignmentOptions o;
  const double at_truth = OverlapHeuristic(p.a, p.b, p.truth, o);
  EXPECT_GE(at_truth, static_cast<double>(p.true_pairs.size()) - 1e-9);
  EXPECT_LE(at_truth, static_cast<double>(p.true_pairs.size()) + 0.1 * p.b.size());
  const Pose2 off = Pose2{5.0, 0.0, 0.0} * p.truth;
  EXPECT_LT(OverlapHeuristic(p.a, p.b, off, o), 0.5 * at_truth);
}

TEST(TransformSearch, RansacStaysTheDefault) {
  EXPECT_EQ(AlignmentOptions{}.search, TransformSearch::kRansac);
  EXPECT_EQ(ParseChoice(kTransformSearch, "arw"), TransformSearch::kAdaptiveRandomWalk);
  EXPECT_EQ(ParseChoice(kTransformSearch, "its"), TransformSearch::kIterativeTranslation);
  EXPECT_EQ(ParseChoice(kTransformSearch, "ransac"), TransformSearch::kRansac);
}

}  // namespace
}  // namespace mapmesh
