#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <unordered_map>
#include <unordered_set>

#include "common/geometry/spatial.h"
#include "common/merge/alignment_fit.h"
#include "common/merge/map_alignment.h"

// Candidate landmark pairs from matched Delaunay triangles (thesis 3.3.2, eq. 51-53, and the
// sorted-sides matcher with patch growing).

namespace mapmesh {
namespace {

using alignment_detail::ForAlignment;
using alignment_detail::Usable;
using alignment_detail::UsableLandmarks;

// A Delaunay triangle: vertices counter-clockwise, each with the length of the side opposite.
struct Triangle {
  std::array<int, 3> v;          // usable indices, counter-clockwise
  Eigen::Vector3d opposite;      // side opposite v[k]
  Eigen::Vector3d sorted;        // the sides ascending: the k-d tree key
  std::array<int, 3> neighbour;  // triangle across the side opposite v[k], or -1
  double sigma = 0.0;            // largest vertex sigma
  double perimeter = 0.0, area = 0.0;
};

std::vector<Triangle> MakeTriangles(const Usable& u, const AlignmentOptions& o) {
  std::vector<Triangle> out;
  std::unordered_map<std::int64_t, std::pair<int, int>> edges;  // edge -> (triangle, its opposite vertex slot)
  for (const auto& f : DelaunayTriangles(u.points)) {
    Triangle t;
    t.v = f;
    for (int k = 0; k < 3; ++k) t.opposite(k) = (u.points[f[(k + 1) % 3]] - u.points[f[(k + 2) % 3]]).norm();
    if (t.opposite.minCoeff() < o.min_side_m) continue;
    t.sorted = t.opposite;
    std::sort(t.sorted.data(), t.sorted.data() + 3);
    t.sigma = std::max({u.sigma[f[0]], u.sigma[f[1]], u.sigma[f[2]]});
    const Eigen::Vector2d e1 = u.points[f[1]] - u.points[f[0]], e2 = u.points[f[2]] - u.points[f[0]];
    t.area = 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());  // equals Heron's formula (thesis eq. 51)
    t.perimeter = t.opposite.sum();
    t.neighbour = {-1, -1, -1};
    const int id = static_cast<int>(out.size());
    for (int k = 0; k < 3; ++k) {
      const int p = f[(k + 1) % 3], q = f[(k + 2) % 3];
      const std::int64_t key = (static_cast<std::int64_t>(std::min(p, q)) << 32) | std::max(p, q);
      auto [it, fresh] = edges.try_emplace(key, id, k);
      if (!fresh) {
        t.neighbour[k] = it->second.first;
        out[it->second.first].neighbour[it->second.second] = id;
      }
    }
    out.push_back(t);
  }
  return out;
}

// A triangle of A matched to one of B: A's vertex v[k] corresponds to B's vertex v[(k + shift) % 3].
struct TriangleMatch {
  int x = 0, y = 0, shift = 0;
};

// The cyclic vertex correspondence (orientation-preserving) under which the sides agree
// within the limit, or -1.
int BestShift(const Triangle& x, const Triangle& y, double limit) {
  int best = -1;
  double best_err = limit;
  for (int r = 0; r < 3; ++r) {
    double err = 0.0;
    for (int k = 0; k < 3; ++k) err = std::max(err, std::abs(x.opposite(k) - y.opposite((k + r) % 3)));
    if (err <= best_err) {
      best_err = err;
      best = r;
    }
  }
  return best;
}

// Grows a patch of matched triangles from a seed match: the triangle across each side of A's
// triangle is matched to the triangle across the corresponding side of B's, with the vertex
// correspondence the shared side fixes, if their sides agree. A true overlap is a connected
// patch of such matches; a coincidental match rarely has even one consistent neighbour.
void GrowPatch(const TriangleMatch& seed, const std::vector<Triangle>& ta, const std::vector<Triangle>& tb, double k,
               double floor, std::unordered_set<std::int64_t>& visited, std::vector<TriangleMatch>& patch) {
  auto key = [](int x, int y) { return (static_cast<std::int64_t>(x) << 32) | y; };
  patch.clear();
  patch.push_back(seed);
  visited.insert(key(seed.x, seed.y));
  for (std::size_t head = 0; head < patch.size(); ++head) {
    const TriangleMatch m = patch[head];
    const Triangle &x = ta[m.x], &y = tb[m.y];
    for (int q = 0; q < 3; ++q) {
      const int xn = x.neighbour[q], yn = y.neighbour[(q + m.shift) % 3];
      if (xn < 0 || yn < 0 || visited.count(key(xn, yn))) continue;
      // The shared side's first endpoint fixes the neighbours' correspondence.
      const int pa = x.v[(q + 1) % 3], pb = y.v[(q + 1 + m.shift) % 3];
      int ja = -1, jb = -1;
      for (int j = 0; j < 3; ++j) {
        if (ta[xn].v[j] == pa) ja = j;
        if (tb[yn].v[j] == pb) jb = j;
      }
      if (ja < 0 || jb < 0) continue;
      const int shift = (jb - ja + 3) % 3;
      const Triangle &xx = ta[xn], &yy = tb[yn];
      const double limit = std::max(floor, k * std::sqrt(2.0 * (xx.sigma * xx.sigma + yy.sigma * yy.sigma)));
      bool agree = true;
      for (int j = 0; j < 3 && agree; ++j) agree = std::abs(xx.opposite(j) - yy.opposite((j + shift) % 3)) <= limit;
      if (!agree) continue;
      visited.insert(key(xn, yn));
      patch.push_back({xn, yn, shift});
    }
  }
}

}  // namespace

std::vector<CandidatePair> MatchTriangles(const LandmarkMap& a_in, const LandmarkMap& b_in, const AlignmentOptions& o,
                                          std::mt19937_64& rng, AlignmentResult* stats) {
  const Usable ua = UsableLandmarks(ForAlignment(a_in, o.min_shape_sigma_m)),
               ub = UsableLandmarks(ForAlignment(b_in, o.min_shape_sigma_m));
  const std::vector<Triangle> ta = ua.points.size() >= 3 ? MakeTriangles(ua, o) : std::vector<Triangle>{};
  const std::vector<Triangle> tb = ub.points.size() >= 3 ? MakeTriangles(ub, o) : std::vector<Triangle>{};
  if (stats) {
    stats->usable_a = static_cast<int>(ua.points.size());
    stats->usable_b = static_cast<int>(ub.points.size());
    stats->triangles_a = static_cast<int>(ta.size());
    stats->triangles_b = static_cast<int>(tb.size());
  }
  std::vector<TriangleMatch> matches;
  const double k = o.side_tolerance_sigmas;
  if (o.matcher == TriangleMatcher::kSortedSides) {
    if (!ta.empty() && !tb.empty()) {
      std::vector<Eigen::Vector3d> keys;
      keys.reserve(ta.size());
      for (const Triangle& t : ta) keys.push_back(t.sorted);
      const KdTree3 tree(keys);
      // Seed from B's triangles in a random order; grow a patch from every match of a seed.
      // Once a large patch is found, a few more seeds look for a competing one, then stop.
      std::vector<int> order(tb.size());
      std::iota(order.begin(), order.end(), 0);
      std::shuffle(order.begin(), order.end(), rng);
      std::unordered_set<std::int64_t> visited;
      visited.reserve(4 * tb.size());
      std::vector<std::vector<TriangleMatch>> patches;
      std::vector<TriangleMatch> patch;
      std::size_t best = 0;
      int seeds_since_best = 0;
      for (int j : order) {
        const Triangle& y = tb[j];
        // Each side depends on two points of each map: sigma_side^2 ~ 2 (sa^2 + sb^2).
        const double floor = o.min_side_tolerance_m;
        const double box = std::max(floor, k * std::sqrt(2.0 * (ua.max_sigma * ua.max_sigma + y.sigma * y.sigma)));
        const Eigen::Vector3d tol = Eigen::Vector3d::Constant(box);
        for (int i : tree.InBox(y.sorted - tol, y.sorted + tol)) {
          if (visited.count((static_cast<std::int64_t>(i) << 32) | j)) continue;
          const int shift = BestShift(
              ta[i], y, std::max(floor, k * std::sqrt(2.0 * (ta[i].sigma * ta[i].sigma + y.sigma * y.sigma))));
          if (shift < 0) continue;
          GrowPatch({i, j, shift}, ta, tb, k, floor, visited, patch);
          if (static_cast<int>(patch.size()) < o.min_consistent_triangles) continue;
          if (patch.size() > best) {
            best = patch.size();
            seeds_since_best = 0;
          }
          patches.push_back(patch);
        }
        // The larger the patch, the less likely a competitor of its size hides in the seeds
        // not tried yet: search on for fewer seeds.
        const int after = std::max(10, static_cast<int>(o.seeds_after_patch * o.patch_stop_triangles /
                                                        std::max<double>(1.0, static_cast<double>(best))));
        if (static_cast<int>(best) >= o.patch_stop_triangles && ++seeds_since_best > after) break;
      }
      // Keep the patches that can compete with the largest.
      for (auto& p : patches) {
        if (p.size() >= o.patch_keep_ratio * static_cast<double>(best)) {
          matches.insert(matches.end(), p.begin(), p.end());
        }
      }
      if (stats) {
        stats->best_patch = static_cast<int>(best);
        stats->patches = static_cast<int>(patches.size());
      }
    }
  } else {
    // Thesis eq. 51-53: s = exp((dperimeter)^2 + (darea)^2) < tau, every pair of triangles.
    const double log_tau = std::log(o.thesis_tau);
    for (std::size_t i = 0; i < ta.size(); ++i) {
      for (std::size_t j = 0; j < tb.size(); ++j) {
        const double df1 = ta[i].perimeter - tb[j].perimeter, df2 = ta[i].area - tb[j].area;
        if (df1 * df1 + df2 * df2 >= log_tau) continue;
        const int shift = BestShift(ta[i], tb[j], std::numeric_limits<double>::infinity());
        matches.push_back({static_cast<int>(i), static_cast<int>(j), shift});
      }
    }
  }
  std::unordered_map<std::int64_t, int> votes;
  for (const TriangleMatch& m : matches) {
    for (int q = 0; q < 3; ++q) {
      const int ia = ua.index[ta[m.x].v[q]], ib = ub.index[tb[m.y].v[(q + m.shift) % 3]];
      ++votes[(static_cast<std::int64_t>(ia) << 32) | ib];
    }
  }
  std::vector<CandidatePair> out;
  out.reserve(votes.size());
  for (const auto& [key, n] : votes) {
    out.push_back({static_cast<int>(key >> 32), static_cast<int>(key & 0xffffffff), n});
  }
  // A fixed order keeps results reproducible for a given generator.
  std::sort(out.begin(), out.end(),
            [](const CandidatePair& x, const CandidatePair& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
  if (stats) stats->candidates = static_cast<int>(out.size());
  return out;
}

}  // namespace mapmesh
