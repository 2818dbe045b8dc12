#include "sim_feeder/world.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

class UniformLandmarksTest : public ::testing::TestWithParam<int> {};

TEST_P(UniformLandmarksTest, RespectTheAreaAndTheMinimumSpacing) {
  LandmarkGeneratorOptions o;
  o.count = 400;
  o.area_m = {-10, 0, 40, 30};
  o.min_spacing_m = 1.5;
  std::mt19937_64 rng(GetParam());
  const auto pts = GenerateUniformLandmarks(o, rng);
  ASSERT_TRUE(pts.has_value());
  ASSERT_EQ(pts->size(), 400u);
  double closest = 1e9;
  for (std::size_t i = 0; i < pts->size(); ++i) {
    EXPECT_TRUE(o.area_m.Contains((*pts)[i]));
    for (std::size_t j = i + 1; j < pts->size(); ++j) closest = std::min(closest, ((*pts)[i] - (*pts)[j]).norm());
  }
  EXPECT_GE(closest, 1.5);
}

INSTANTIATE_TEST_SUITE_P(Seeds, UniformLandmarksTest, ::testing::Range(1, 6));

TEST(UniformLandmarks, ImpossibleSpacingFailsCleanly) {
  LandmarkGeneratorOptions o;
  o.count = 50;
  o.area_m = {0, 0, 3, 3};
  o.min_spacing_m = 1.0;
  std::mt19937_64 rng(1);
  EXPECT_FALSE(GenerateUniformLandmarks(o, rng).has_value());
}

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

TEST(DistanceToPolyline, SegmentsAndEnds) {
  const Polyline l{{0, 0}, {10, 0}, {10, 10}};
  EXPECT_NEAR(DistanceToPolyline({5, 3}, l), 3.0, 1e-12);
  EXPECT_NEAR(DistanceToPolyline({12, 5}, l), 2.0, 1e-12);
  EXPECT_NEAR(DistanceToPolyline({-3, -4}, l), 5.0, 1e-12);
}

class ParkTest : public ::testing::TestWithParam<int> {};

TEST_P(ParkTest, TreesLineThePathsAndKeepOffThem) {
  LandmarkGeneratorOptions o;
  o.type = LandmarkLayout::kPark;
  o.count = 250;
  o.area_m = {0, 0, 60, 60};
  o.paths = 4;
  o.path_width_m = 5;
  o.scatter_fraction = 0.2;
  o.min_spacing_m = 1.5;
  std::mt19937_64 rng(GetParam());
  const auto park = GeneratePark(o, rng);
  ASSERT_TRUE(park.has_value());
  ASSERT_EQ(park->landmarks.size(), 250u);
  ASSERT_EQ(park->paths.size(), 4u);
  int near_a_path = 0;
  for (std::size_t i = 0; i < park->landmarks.size(); ++i) {
    const Eigen::Vector2d& p = park->landmarks[i];
    EXPECT_TRUE(o.area_m.Contains(p));
    double nearest = 1e9;
    for (const Polyline& l : park->paths) nearest = std::min(nearest, DistanceToPolyline(p, l));
    EXPECT_GE(nearest, 2.5 - 1e-9);  // never on a footpath
    near_a_path += nearest < 2.5 + 5.0;
    for (std::size_t j = i + 1; j < park->landmarks.size(); ++j) {
      EXPECT_GE((p - park->landmarks[j]).norm(), 1.5);
    }
  }
  // Most trees stand within a path width of a path's edge (uniform scatter would put only
  // a minority there).
  EXPECT_GT(near_a_path, 0.7 * 250);
  for (const Polyline& l : park->paths) {
    const Eigen::Vector2d s = l.front();
    const bool on_edge = std::abs(s.x()) < 1e-9 || std::abs(s.x() - 60) < 1e-9 || std::abs(s.y()) < 1e-9 ||
                         std::abs(s.y() - 60) < 1e-9;
    EXPECT_TRUE(on_edge);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, ParkTest, ::testing::Range(1, 4));

TEST(DiscLandmarks, StayInTheDiscWithTheSpacing) {
  LandmarkGeneratorOptions o;
  o.type = LandmarkLayout::kDisc;
  o.count = 100;
  o.center_m = {5, -5};
  o.radius_m = 30;
  o.min_spacing_m = 1.0;
  std::mt19937_64 rng(2);
  const auto pts = GenerateDiscLandmarks(o, rng);
  ASSERT_TRUE(pts.has_value());
  ASSERT_EQ(pts->size(), 100u);
  int inner = 0;
  for (std::size_t i = 0; i < pts->size(); ++i) {
    EXPECT_LE(((*pts)[i] - o.center_m).norm(), 30.0);
    inner += ((*pts)[i] - o.center_m).norm() < 15.0;
  }
  // Uniform radius puts about half the points in the inner half-radius (a quarter of the area).
  EXPECT_GT(inner, 35);
}

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

// A spacing far below the landmarks' mean distance once gave every point the same grid cell
// (its index cast from a huge quotient), so each test compared against every accepted point:
// 10^5 landmarks took 5·10^9 distances. The grid's cells now follow the area per landmark.
class TinySpacingTest : public ::testing::TestWithParam<LandmarkLayout> {};

TEST_P(TinySpacingTest, EachCandidateIsTestedAgainstAFewNeighboursOnly) {
  LandmarkGeneratorOptions o;
  o.type = GetParam();
  o.count = 100000;
  o.area_m = {0, 0, 50, 50};
  o.center_m = {25, 25};
  o.radius_m = 25;
  o.min_spacing_m = 1e-300;
  std::mt19937_64 rng(3);
  GenerationStats stats;
  std::size_t placed = 0;
  if (o.type == LandmarkLayout::kPark) {
    const auto park = GeneratePark(o, rng, &stats);
    ASSERT_TRUE(park.has_value());
    placed = park->landmarks.size();
  } else {
    const auto pts = o.type == LandmarkLayout::kDisc ? GenerateDiscLandmarks(o, rng, &stats)
                                                     : GenerateUniformLandmarks(o, rng, &stats);
    ASSERT_TRUE(pts.has_value());
    placed = pts->size();
  }
  EXPECT_EQ(placed, 100000u);
  EXPECT_EQ(stats.attempts, 100000);  // no two candidates are 1e-300 m apart
  // About one landmark per cell, and 9 cells per test (the disc, denser at its centre, a few more).
  EXPECT_GT(stats.cells, 100000u / 4);
  EXPECT_LT(stats.distance_checks, 30L * 100000);
}

INSTANTIATE_TEST_SUITE_P(Types, TinySpacingTest,
                         ::testing::Values(LandmarkLayout::kUniform, LandmarkLayout::kDisc, LandmarkLayout::kPark));

// The densest world the scenario check lets through (0.5 landmarks per spacing²) is placed
// well within the generators' attempt budget, without testing many distances.
TEST(UniformLandmarks, DensestAllowedWorldIsPlacedWithinTheBudget) {
  LandmarkGeneratorOptions o;
  o.count = 20000;
  o.area_m = {0, 0, 100, 100};
  o.min_spacing_m = 0.5;  // 0.5 * 100 * 100 / 0.5² = 20000
  std::mt19937_64 rng(5);
  GenerationStats stats;
  const auto pts = GenerateUniformLandmarks(o, rng, &stats);
  ASSERT_TRUE(pts.has_value());
  EXPECT_EQ(pts->size(), 20000u);
  EXPECT_LT(stats.attempts, 50L * 20000);
  EXPECT_LT(stats.distance_checks, 30 * stats.attempts);
}

}  // namespace
}  // namespace mapmesh
