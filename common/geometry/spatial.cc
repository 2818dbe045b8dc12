// The one translation unit that includes CGAL (slow to compile): keep it that way.

#include "common/geometry/spatial.h"

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Fuzzy_iso_box.h>
#include <CGAL/Kd_tree.h>
#include <CGAL/Search_traits_3.h>
#include <CGAL/Search_traits_adapter.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <CGAL/property_map.h>

#include <boost/iterator/counting_iterator.hpp>

namespace mapmesh {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Triangulation_vertex_base_with_info_2<int, Kernel>;
using Tds = CGAL::Triangulation_data_structure_2<Vb>;
using Delaunay = CGAL::Delaunay_triangulation_2<Kernel, Tds>;

// Search traits over point indices: the tree stores ints and reads coordinates through a
// property map, so query results come back as indices.
template <typename Point>
struct IndexMap {
  using key_type = int;
  using value_type = Point;
  using reference = const Point&;
  using category = boost::readable_property_map_tag;
  const std::vector<Point>* points;
  friend reference get(const IndexMap& m, int i) { return (*m.points)[i]; }
};

using Point3 = Kernel::Point_3;
using Traits3 = CGAL::Search_traits_adapter<int, IndexMap<Point3>, CGAL::Search_traits_3<Kernel>>;
using Tree3 = CGAL::Kd_tree<Traits3>;
using Box3 = CGAL::Fuzzy_iso_box<Traits3>;

}  // namespace

std::vector<std::array<int, 3>> DelaunayTriangles(const std::vector<Eigen::Vector2d>& points) {
  std::vector<std::pair<Kernel::Point_2, int>> input;
  input.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    input.emplace_back(Kernel::Point_2(points[i].x(), points[i].y()), static_cast<int>(i));
  }
  Delaunay dt;
  dt.insert(input.begin(), input.end());
  std::vector<std::array<int, 3>> out;
  if (dt.dimension() < 2) return out;
  out.reserve(dt.number_of_faces());
  for (auto f = dt.finite_faces_begin(); f != dt.finite_faces_end(); ++f) {
    out.push_back({f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()});
  }
  return out;
}

struct KdTree3::Impl {
  std::vector<Point3> points;
  std::unique_ptr<Tree3> tree;
};

KdTree3::KdTree3(const std::vector<Eigen::Vector3d>& points) : impl_(std::make_unique<Impl>()) {
  impl_->points.reserve(points.size());
  for (const auto& p : points) impl_->points.emplace_back(p.x(), p.y(), p.z());
  impl_->tree = std::make_unique<Tree3>(boost::counting_iterator<int>(0),
                                        boost::counting_iterator<int>(static_cast<int>(points.size())),
                                        Tree3::Splitter(), Traits3(IndexMap<Point3>{&impl_->points}));
  impl_->tree->build();
}

KdTree3::~KdTree3() = default;

std::vector<int> KdTree3::InBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) const {
  std::vector<int> out;
  const Box3 box(Point3(lo.x(), lo.y(), lo.z()), Point3(hi.x(), hi.y(), hi.z()), 0.0,
                 Traits3(IndexMap<Point3>{&impl_->points}));
  impl_->tree->search(std::back_inserter(out), box);
  return out;
}

}  // namespace mapmesh
