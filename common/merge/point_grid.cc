#include "common/merge/point_grid.h"

#include <algorithm>
#include <cmath>

namespace mapmesh {

PointGrid2::PointGrid2(const std::vector<Eigen::Vector2d>& points) : points_(points) {
  Eigen::Vector2d hi = Eigen::Vector2d::Constant(-INFINITY);
  lo_ = Eigen::Vector2d::Constant(INFINITY);
  int finite = 0;
  for (const Eigen::Vector2d& p : points_) {
    if (!p.allFinite()) continue;
    lo_ = lo_.cwiseMin(p);
    hi = hi.cwiseMax(p);
    ++finite;
  }
  if (finite == 0) return;
  // About one point per cell over the bounding box's longer side (a map along one path has
  // cells along it, not a square grid of empty ones).
  const double extent = (hi - lo_).maxCoeff();
  const double per_side = std::ceil(std::sqrt(static_cast<double>(finite)));
  cell_ = extent > 0.0 ? extent / per_side : 1.0;
  // Two cells more than per_side at most, whatever the rounding.
  nx_ = static_cast<int>(std::min(per_side + 1.0, std::floor((hi.x() - lo_.x()) / cell_))) + 1;
  ny_ = static_cast<int>(std::min(per_side + 1.0, std::floor((hi.y() - lo_.y()) / cell_))) + 1;
  std::vector<int> cell_of(points_.size(), -1);
  start_.assign(static_cast<std::size_t>(nx_) * ny_ + 1, 0);
  for (std::size_t i = 0; i < points_.size(); ++i) {
    if (!points_[i].allFinite()) continue;
    const int cx = std::min(nx_ - 1, static_cast<int>((points_[i].x() - lo_.x()) / cell_));
    const int cy = std::min(ny_ - 1, static_cast<int>((points_[i].y() - lo_.y()) / cell_));
    cell_of[i] = cy * nx_ + cx;
    ++start_[cell_of[i] + 1];
  }
  for (std::size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
  order_.resize(finite);
  std::vector<int> fill(start_.begin(), start_.end() - 1);
  for (std::size_t i = 0; i < points_.size(); ++i) {
    if (cell_of[i] >= 0) order_[fill[cell_of[i]]++] = static_cast<int>(i);  // ascending within a cell
  }
}

bool PointGrid2::AnyInRadius(const Eigen::Vector2d& center, double radius) const {
  return Visit(center, radius, [](int) { return true; });
}

}  // namespace mapmesh
