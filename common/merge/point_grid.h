#pragma once
// Radius queries over a small set of 2D points (a map's landmarks, a global map's clusters):
// the points are bucketed in a uniform grid of about one point per cell, so that a query reads
// only the few cells its circle overlaps. It replaced CGAL's k-d tree, whose walk and answer
// vectors were 17 % of a 64-agent lab run (docs/BENCHMARKS.md, S1).

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

namespace mapmesh {

class PointGrid2 {
 public:
  // Non-finite points are kept in the numbering but never found.
  explicit PointGrid2(const std::vector<Eigen::Vector2d>& points);
  // Calls f(index) for each point within `radius` of center (distance <= radius), in no
  // particular order, until f returns true; returns whether it did. A negative or NaN radius
  // finds nothing; an infinite one finds every finite point. No allocation.
  template <typename F>
  bool Visit(const Eigen::Vector2d& center, double radius, F&& f) const;
  // Whether Visit would find any point.
  bool AnyInRadius(const Eigen::Vector2d& center, double radius) const;

 private:
  std::vector<Eigen::Vector2d> points_;
  Eigen::Vector2d lo_ = Eigen::Vector2d::Zero();
  double cell_ = 1.0;
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_;  // CSR: the points of cell c are order_[start_[c] .. start_[c + 1])
  std::vector<int> order_;
};

template <typename F>
bool PointGrid2::Visit(const Eigen::Vector2d& center, double radius, F&& f) const {
  if (nx_ == 0 || !(radius >= 0.0) || !center.allFinite()) return false;
  // The cells the circle's bounding box overlaps, clamped to the grid while still in doubles.
  const auto range = [&](double c, double lo, int n, int* first, int* last) {
    const double a = std::floor((c - radius - lo) / cell_), b = std::floor((c + radius - lo) / cell_);
    if (b < 0.0 || a > n - 1) return false;
    *first = static_cast<int>(std::max(a, 0.0));
    *last = static_cast<int>(std::min(b, static_cast<double>(n - 1)));
    return true;
  };
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  if (!range(center.x(), lo_.x(), nx_, &x0, &x1) || !range(center.y(), lo_.y(), ny_, &y0, &y1)) return false;
  const double r2 = radius * radius;
  for (int cy = y0; cy <= y1; ++cy) {
    for (int cx = x0; cx <= x1; ++cx) {
      const int c = cy * nx_ + cx;
      for (int k = start_[c]; k < start_[c + 1]; ++k) {
        const int i = order_[k];
        if ((points_[i] - center).squaredNorm() <= r2 && f(i)) return true;
      }
    }
  }
  return false;
}

}  // namespace mapmesh
