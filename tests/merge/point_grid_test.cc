#include "common/merge/point_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

namespace mapmesh {
namespace {

// What the grid visits, ascending.
std::vector<int> InRadius(const PointGrid2& grid, const Eigen::Vector2d& c, double radius) {
  std::vector<int> out;
  grid.Visit(c, radius, [&](int i) {
    out.push_back(i);
    return false;
  });
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<int> BruteForce(const std::vector<Eigen::Vector2d>& points, const Eigen::Vector2d& c, double radius) {
  std::vector<int> out;
  if (!(radius >= 0.0) || !c.allFinite()) return out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (points[i].allFinite() && (points[i] - c).norm() <= radius) out.push_back(static_cast<int>(i));
  }
  return out;
}

// Points as maps hold them: scattered, along a line (one path), in a tight cluster, with
// repeats; queries inside and far outside, radii from 0 to beyond the extent.
std::vector<Eigen::Vector2d> Points(int layout, int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-30.0, 30.0), small(-0.01, 0.01);
  std::vector<Eigen::Vector2d> p;
  for (int i = 0; i < n; ++i) {
    switch (layout) {
      case 0: p.emplace_back(u(rng), u(rng)); break;
      case 1: p.emplace_back(u(rng), 5.0 + small(rng)); break;
      case 2: p.emplace_back(small(rng), small(rng)); break;
      default: p.emplace_back(std::round(u(rng) / 10.0) * 10.0, 0.0); break;  // repeated points
    }
  }
  return p;
}

TEST(PointGrid2, FindsExactlyThePointsWithinTheRadiusInAscendingOrder) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> q(-45.0, 45.0), r(0.0, 1.0);
  for (int layout = 0; layout < 4; ++layout) {
    for (int n : {1, 2, 7, 64, 300}) {
      const std::vector<Eigen::Vector2d> points = Points(layout, n, rng);
      const PointGrid2 grid(points);
      for (int k = 0; k < 200; ++k) {
        const Eigen::Vector2d c(q(rng), q(rng));
        // Mostly map-sized radii, some zero and some larger than the whole set.
        const double radius = k % 10 == 0 ? 0.0 : (k % 10 == 1 ? 100.0 : 4.0 * r(rng));
        const Eigen::Vector2d at = k % 3 == 0 ? points[k % n] : c;  // on a point too
        const std::vector<int> want = BruteForce(points, at, radius);
        EXPECT_EQ(InRadius(grid, at, radius), want) << "layout " << layout << " n " << n << " query " << k;
        EXPECT_EQ(grid.AnyInRadius(at, radius), !want.empty());
      }
    }
  }
}

TEST(PointGrid2, IgnoresNonFinitePointsAndBadQueries) {
  const double inf = std::numeric_limits<double>::infinity(), nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<Eigen::Vector2d> points = {{0, 0}, {nan, 1}, {1, 0}, {inf, 0}, {2, 2}};
  const PointGrid2 grid(points);
  EXPECT_EQ(InRadius(grid, {0, 0}, 1.0), (std::vector<int>{0, 2}));
  EXPECT_EQ(InRadius(grid, {0, 0}, inf), (std::vector<int>{0, 2, 4}));
  EXPECT_TRUE(InRadius(grid, {0, 0}, nan).empty());
  EXPECT_TRUE(InRadius(grid, {0, 0}, -1.0).empty());
  EXPECT_TRUE(InRadius(grid, {nan, 0}, 5.0).empty());
  EXPECT_FALSE(grid.AnyInRadius({100, 100}, 5.0));
  EXPECT_TRUE(InRadius(PointGrid2({}), {0, 0}, inf).empty());
  EXPECT_TRUE(InRadius(PointGrid2({{nan, nan}}), {0, 0}, inf).empty());
}

}  // namespace
}  // namespace mapmesh
