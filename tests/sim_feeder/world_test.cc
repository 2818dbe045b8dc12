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
