#pragma once
// Computational geometry for map alignment, backed by CGAL. This header keeps CGAL out of
// every other translation unit: it is included only by spatial.cc.

#include <Eigen/Core>
#include <array>
#include <memory>
#include <vector>

namespace mapmesh {

// The Delaunay triangulation of points (CGAL, O(n log n)), as index triples in
// counter-clockwise order. Points must be finite; repeated points are used once; fewer than
// three non-collinear points give no triangle.
std::vector<std::array<int, 3>> DelaunayTriangles(const std::vector<Eigen::Vector2d>& points);

// A k-d tree over 3D points answering box queries (CGAL spatial searching).
class KdTree3 {
 public:
  explicit KdTree3(const std::vector<Eigen::Vector3d>& points);
  ~KdTree3();
  KdTree3(const KdTree3&) = delete;
  KdTree3& operator=(const KdTree3&) = delete;
  // Indices of the points p with lo <= p <= hi (component-wise).
  std::vector<int> InBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mapmesh
