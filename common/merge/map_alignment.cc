#include "common/merge/map_alignment.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <limits>
#include <unordered_map>
#include <unordered_set>

#include "common/geometry/rigid_fit.h"
#include "common/merge/spatial.h"
#include "common/metrics/chi2.h"

namespace mapmesh {
namespace {

// The landmarks of a map that alignment can use.
struct Usable {
  std::vector<int> index;               // into the map's landmarks
  std::vector<Eigen::Vector2d> points;
  std::vector<double> sigma;            // sqrt of the covariance's largest eigenvalue
  double max_sigma = 0.0;
};

double LargestSigma(const Eigen::Matrix2d& c) {
  const double tr = c.trace(), det = c.determinant();
  const double disc = std::sqrt(std::max(0.0, tr * tr / 4.0 - det));
  return std::sqrt(std::max(0.0, tr / 2.0 + disc));
}

Usable UsableLandmarks(const LandmarkMap& m) {
  Usable u;
  for (std::size_t i = 0; i < m.landmarks.size(); ++i) {
    const Landmark& l = m.landmarks[i];
    if (!l.mean.allFinite() || !IsValidCovariance(l.cov)) continue;
    u.index.push_back(static_cast<int>(i));
    u.points.push_back(l.mean);
    u.sigma.push_back(LargestSigma(l.cov));
    u.max_sigma = std::max(u.max_sigma, u.sigma.back());
  }
  return u;
}

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

// Residual a - T(b) of a pair and its squared Mahalanobis distance under T.
double PairD2(const Landmark& la, const Landmark& lb, const Pose2& t, Eigen::Vector2d* r = nullptr) {
  const Eigen::Matrix2d rot = t.Rotation();
  const Eigen::Vector2d res = la.mean - t.Apply(lb.mean);
  const Eigen::Matrix2d c = la.cov + rot * lb.cov * rot.transpose();
  if (r) *r = res;
  const double det = c.determinant();
  if (!(det > 0.0)) return std::numeric_limits<double>::infinity();
  return res.dot(c.inverse() * res);
}

struct Hypothesis {
  Pose2 t;
  int support = -1;
  double cost = std::numeric_limits<double>::infinity();
  bool BetterThan(const Hypothesis& o) const { return support > o.support || (support == o.support && cost < o.cost); }
};

// The information matrix of (x, y, theta) from the pairs at t, and the gradient of the
// weighted squared residuals.
Eigen::Matrix3d Information(const LandmarkMap& a, const LandmarkMap& b, const std::vector<std::pair<int, int>>& pairs,
                            const Pose2& t, Eigen::Vector3d* gradient) {
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  const Eigen::Matrix2d rot = t.Rotation();
  Eigen::Matrix2d drot;
  drot << -std::sin(t.theta), -std::cos(t.theta), std::cos(t.theta), -std::sin(t.theta);
  for (const auto& [ia, ib] : pairs) {
    const Landmark &la = a.landmarks[ia], &lb = b.landmarks[ib];
    const Eigen::Vector2d r = la.mean - t.Apply(lb.mean);
    const Eigen::Matrix2d c = la.cov + rot * lb.cov * rot.transpose();
    const Eigen::LDLT<Eigen::Matrix2d> ldlt(c);
    if (ldlt.info() != Eigen::Success || !(c.determinant() > 0)) continue;
    Eigen::Matrix<double, 2, 3> j;
    j.leftCols<2>() = -Eigen::Matrix2d::Identity();
    j.col(2) = -drot * lb.mean;
    const Eigen::Matrix<double, 3, 2> jt_cinv = ldlt.solve(j).transpose();
    info += jt_cinv * j;
    g += jt_cinv * r;
  }
  if (gradient) *gradient = g;
  return info;
}

// Weighted least squares (Gauss-Newton) of the transform over pairs; returns the
// information matrix of (x, y, theta) at the solution.
Eigen::Matrix3d Refine(const LandmarkMap& a, const LandmarkMap& b, const std::vector<std::pair<int, int>>& pairs,
                       Pose2* t) {
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  for (int it = 0; it < 6; ++it) {
    Eigen::Vector3d g;
    info = Information(a, b, pairs, *t, &g);
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(info);
    if (!lu.isInvertible()) break;
    const Eigen::Vector3d step = -lu.solve(g);
    t->x += step(0);
    t->y += step(1);
    t->theta = WrapAngle(t->theta + step(2));
    if (step.head<2>().norm() < 1e-9 && std::abs(step(2)) < 1e-12) break;
  }
  return info;
}

// The map as alignment compares it (consensus, matching, the tests): where the map's shape
// precision is known and tighter than a landmark's marginal, the landmark counts with that
// precision (isotropic), since a rigid transform absorbs the pose error that the marginals
// mostly hold. With every_landmark (the fit), all landmarks count with it: the marginals would
// weigh the landmarks near the map's origin up to a hundred times more than the rest (a SLAM
// map's marginals grow with the distance travelled) and the fit would follow those few; alike,
// it is the least-squares fit of the shapes (line of three: robot 3's landmarks placed at
// 0.031 m by the marginals' fit, 0.017 m by this one, on the final maps). Shape precision never
// counts below the floor: landmarks are not points, and real maps' shapes are rarely as good as
// their filters believe (MRCLAM: 2-4 cm claimed, 4-11 cm found).
LandmarkMap ForAlignment(const LandmarkMap& m, double floor_m, bool every_landmark = false) {
  if (!(m.shape_sigma_m > 0.0) || !std::isfinite(m.shape_sigma_m)) return m;
  LandmarkMap out = m;
  const double s = std::max(m.shape_sigma_m, floor_m), v = s * s;
  for (Landmark& l : out.landmarks) {
    if (l.mean.allFinite() && IsValidCovariance(l.cov) && (every_landmark || LargestSigma(l.cov) * LargestSigma(l.cov) > v)) {
      l.cov = v * Eigen::Matrix2d::Identity();
    }
  }
  return out;
}

// One-to-one pairs, closest first.
std::vector<std::pair<int, int>> OneToOne(std::vector<std::tuple<double, int, int>> scored) {
  std::sort(scored.begin(), scored.end());
  std::unordered_map<int, bool> used_a, used_b;
  std::vector<std::pair<int, int>> out;
  for (const auto& [d2, ia, ib] : scored) {
    if (used_a[ia] || used_b[ib]) continue;
    used_a[ia] = used_b[ib] = true;
    out.emplace_back(ia, ib);
  }
  return out;
}

}  // namespace

std::string_view ToString(AlignmentVerdict v) {
  switch (v) {
    case AlignmentVerdict::kAccepted: return "accepted";
    case AlignmentVerdict::kTooFewLandmarks: return "too_few_landmarks";
    case AlignmentVerdict::kNoTriangles: return "no_triangles";
    case AlignmentVerdict::kNoCandidates: return "no_candidates";
    case AlignmentVerdict::kTooFewInliers: return "too_few_inliers";
    case AlignmentVerdict::kResidualsTooLarge: return "residuals_too_large";
    case AlignmentVerdict::kAmbiguous: return "ambiguous";
    case AlignmentVerdict::kInconsistentOverlap: return "inconsistent_overlap";
    case AlignmentVerdict::kDegenerate: return "degenerate";
  }
  return "unknown";
}

std::optional<Pose2> TwoPointTransform(const Eigen::Vector2d& a1, const Eigen::Vector2d& a2,
                                       const Eigen::Vector2d& b1, const Eigen::Vector2d& b2) {
  // Eq. 57-59: [T(p1); T(p2)] = [S1 I; S2 I] theta with S = [x -y; y x]; with M = S1 - S2,
  // [cos, sin] = M^-1 (q1 - q2) (M = [dx -dy; dy dx], inverted by hand).
  const Eigen::Vector2d d = b1 - b2, q = a1 - a2;
  const double den = d.squaredNorm();
  if (!(den > 1e-18)) return std::nullopt;
  const double c = (d.x() * q.x() + d.y() * q.y()) / den;
  const double s = (d.x() * q.y() - d.y() * q.x()) / den;
  const double theta = std::atan2(s, c);  // projected onto a rotation
  const Pose2 rot{0.0, 0.0, theta};
  const Eigen::Vector2d t = 0.5 * (a1 + a2) - rot.Apply(0.5 * (b1 + b2));
  return Pose2{t.x(), t.y(), theta};
}

std::vector<CandidatePair> MatchTriangles(const LandmarkMap& a_in, const LandmarkMap& b_in, const AlignmentOptions& o,
                                          std::mt19937_64& rng, AlignmentResult* stats) {
  const Usable ua = UsableLandmarks(ForAlignment(a_in, o.min_shape_sigma_m)), ub = UsableLandmarks(ForAlignment(b_in, o.min_shape_sigma_m));
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
          const int shift =
              BestShift(ta[i], y, std::max(floor, k * std::sqrt(2.0 * (ta[i].sigma * ta[i].sigma + y.sigma * y.sigma))));
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
  std::sort(out.begin(), out.end(), [](const CandidatePair& x, const CandidatePair& y) {
    return x.a != y.a ? x.a < y.a : x.b < y.b;
  });
  if (stats) stats->candidates = static_cast<int>(out.size());
  return out;
}

namespace {

// Squared Mahalanobis (or Euclidean) distance of a pair under t, or infinity outside the gate.
double GatedD2(const Landmark& la, const Landmark& lb, const Pose2& t, const AlignmentOptions& o, double gate) {
  if (o.distance == ConsensusDistance::kEuclidean) {
    const double e = (la.mean - t.Apply(lb.mean)).norm();
    return e < o.euclidean_gate_m ? e * e : std::numeric_limits<double>::infinity();
  }
  const double d2 = PairD2(la, lb, t);
  return d2 < gate ? d2 : std::numeric_limits<double>::infinity();
}

// From a transform and its first inliers: guided matching (optional), refinement, the
// transform's covariance and the acceptance tests. a and b are the maps as alignment compares
// them, a_in and b_in as given (for the fit's weights and the covariance).
void Conclude(const LandmarkMap& a_in, const LandmarkMap& b_in, const LandmarkMap& a, const LandmarkMap& b, Pose2 t,
              std::vector<std::pair<int, int>> inliers, const AlignmentOptions& o, bool guided, AlignmentResult& r) {
  const double gate = Chi2Quantile(o.gate_probability, 2);
  const LandmarkMap fit_a = ForAlignment(a_in, o.min_shape_sigma_m, /*every_landmark=*/true);
  const LandmarkMap fit_b = ForAlignment(b_in, o.min_shape_sigma_m, /*every_landmark=*/true);
  if (!inliers.empty()) Refine(fit_a, fit_b, inliers, &t);
  if (guided) {
    const Usable ua = UsableLandmarks(a), ub = UsableLandmarks(b);
    if (!ua.points.empty() && !ub.points.empty()) {
      const KdTree2 tree(ua.points);
      for (int round = 0; round < 2; ++round) {
        std::vector<std::tuple<double, int, int>> scored;
        const double radius_scale = o.distance == ConsensusDistance::kEuclidean ? 0.0 : std::sqrt(gate);
        for (std::size_t j = 0; j < ub.points.size(); ++j) {
          const Eigen::Vector2d p = t.Apply(ub.points[j]);
          const double radius = o.distance == ConsensusDistance::kEuclidean
                                    ? o.euclidean_gate_m
                                    : radius_scale * std::sqrt(ua.max_sigma * ua.max_sigma + ub.sigma[j] * ub.sigma[j]);
          for (int i : tree.InRadius(p, radius)) {
            const double d2 = GatedD2(a.landmarks[ua.index[i]], b.landmarks[ub.index[j]], t, o, gate);
            if (std::isfinite(d2)) scored.emplace_back(d2, ua.index[i], ub.index[j]);
          }
        }
        inliers = OneToOne(std::move(scored));
        Refine(fit_a, fit_b, inliers, &t);
      }
    }
  }

  // Where the transform lays B over ground A has mapped, B's landmarks should find partners.
  {
    const Usable ua = UsableLandmarks(a), ub = UsableLandmarks(b);
    if (!ua.points.empty()) {
      const KdTree2 tree(ua.points);
      for (const Eigen::Vector2d& p : ub.points) {
        if (!tree.InRadius(t.Apply(p), o.coverage_radius_m).empty()) ++r.covered;
      }
    }
  }
  r.transform = t;
  r.inliers = inliers;
  for (const auto& [ia, ib] : inliers) r.residual_chi2 += PairD2(a.landmarks[ia], b.landmarks[ib], t);
  const int ni = static_cast<int>(inliers.size());
  if (ni < o.min_inliers) {
    r.verdict = AlignmentVerdict::kTooFewInliers;
    return;
  }
  const Eigen::Matrix3d info = Information(a_in, b_in, inliers, t, nullptr);
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(info);
  if (!lu.isInvertible() || lu.rcond() < 1e-12) {
    r.verdict = AlignmentVerdict::kDegenerate;
    return;
  }
  // Refine sums the inliers' information as if their errors were independent; with unknown
  // correlation, CI with equal weights keeps the average instead.
  const double scale = o.landmark_errors == LandmarkErrors::kIndependent ? 1.0 : static_cast<double>(ni);
  r.cov = scale * info.inverse();
  r.cov = 0.5 * (r.cov + r.cov.transpose()).eval();
  // 2 residual dimensions per inlier, 3 parameters fitted: chi-square with 2n - 4 dof (the
  // even number just below) bounds the sum.
  r.residual_bound = o.residual_tolerance * Chi2Quantile(o.residual_probability, std::max(2, 2 * ni - 4));
  if (!std::isfinite(r.residual_chi2) || r.residual_chi2 > r.residual_bound) {
    r.verdict = AlignmentVerdict::kResidualsTooLarge;
    return;
  }
  if (ni < o.min_overlap_ratio * r.covered) {
    r.verdict = AlignmentVerdict::kInconsistentOverlap;
    return;
  }
  if (r.runner_up_support >= o.ambiguity_ratio * r.best_support && r.best_support > 0) {
    r.verdict = AlignmentVerdict::kAmbiguous;
    return;
  }
  r.verdict = AlignmentVerdict::kAccepted;
}

}  // namespace

AlignmentResult RansacAlign(const LandmarkMap& a_in, const LandmarkMap& b_in, const std::vector<CandidatePair>& cand,
                            const AlignmentOptions& o, std::mt19937_64& rng) {
  // Consensus, matching and the tests compare shapes; the transform's covariance comes from
  // the marginals (below).
  const LandmarkMap a = ForAlignment(a_in, o.min_shape_sigma_m), b = ForAlignment(b_in, o.min_shape_sigma_m);
  AlignmentResult r;
  r.candidates = static_cast<int>(cand.size());
  if (cand.size() < 2) {
    r.verdict = AlignmentVerdict::kNoCandidates;
    return r;
  }
  const double gate = Chi2Quantile(o.gate_probability, 2);
  auto inlier_d2 = [&](const CandidatePair& c, const Pose2& t) {
    return GatedD2(a.landmarks[c.a], b.landmarks[c.b], t, o, gate);
  };
  // Support: the landmarks the hypothesis pairs, each counted once on each side (where
  // candidates are dense, one landmark can sit in many compatible pairs). Each hypothesis
  // also marks its inlier candidates, and counts those it shares with the best and the
  // runner-up so far: two hypotheses that share most of their inliers are one alignment,
  // however far apart their parameters (a long map turns a small rotation difference into
  // metres); two that share few are different alignments, however close.
  struct Marked : Hypothesis {
    std::vector<char> in;
    int pairs = 0;
  };
  std::vector<int> stamp_a(a.landmarks.size(), -1), stamp_b(b.landmarks.size(), -1);
  std::vector<char> scratch(cand.size(), 0);
  int evaluation = 0;
  Marked best, runner;
  best.in.assign(cand.size(), 0);
  runner.in.assign(cand.size(), 0);
  int shared_best = 0, shared_runner = 0;
  auto evaluate = [&](const Pose2& t) {
    Hypothesis h{t, 0, 0.0};
    int na = 0, nb = 0, pairs = 0;
    shared_best = shared_runner = 0;
    ++evaluation;
    for (std::size_t i = 0; i < cand.size(); ++i) {
      const CandidatePair& c = cand[i];
      const double d2 = inlier_d2(c, t);
      scratch[i] = std::isfinite(d2);
      if (!scratch[i]) continue;
      ++pairs;
      shared_best += best.in[i];
      shared_runner += runner.in[i];
      if (stamp_a[c.a] != evaluation) {
        stamp_a[c.a] = evaluation;
        ++na;
      }
      if (stamp_b[c.b] != evaluation) {
        stamp_b[c.b] = evaluation;
        ++nb;
      }
      h.cost += d2;
    }
    h.support = std::min(na, nb);
    return std::pair<Hypothesis, int>(h, pairs);
  };
  auto same = [&](int shared, int pairs_x, int pairs_y) {
    return shared >= o.same_alignment_overlap * std::min(pairs_x, pairs_y);
  };

  std::uniform_int_distribution<std::size_t> pick(0, cand.size() - 1);
  const double n = static_cast<double>(cand.size());
  long bound = o.max_iterations;
  const double rigid_tol = o.distance == ConsensusDistance::kEuclidean ? 2.0 * o.euclidean_gate_m : 0.0;
  int it = 0;
  for (; it < bound && it < o.max_iterations; ++it) {
    const CandidatePair& c1 = cand[pick(rng)];
    const CandidatePair& c2 = cand[pick(rng)];
    if (c1.a == c2.a || c1.b == c2.b) continue;
    const Landmark &a1 = a.landmarks[c1.a], &a2 = a.landmarks[c2.a], &b1 = b.landmarks[c1.b], &b2 = b.landmarks[c2.b];
    // A rigid motion keeps distances: reject samples that cannot be one.
    const double dist_gap = std::abs((a1.mean - a2.mean).norm() - (b1.mean - b2.mean).norm());
    const double tol = rigid_tol > 0 ? rigid_tol
                                     : 3.0 * std::sqrt(std::pow(LargestSigma(a1.cov), 2) + std::pow(LargestSigma(a2.cov), 2) +
                                                       std::pow(LargestSigma(b1.cov), 2) + std::pow(LargestSigma(b2.cov), 2));
    if (dist_gap > tol) continue;
    const std::optional<Pose2> t = TwoPointTransform(a1.mean, a2.mean, b1.mean, b2.mean);
    if (!t) continue;
    const auto [h, pairs] = evaluate(*t);
    const bool same_as_best = best.support >= 0 && same(shared_best, pairs, best.pairs);
    if (h.BetterThan(best)) {
      const bool runner_same_as_h = runner.support >= 0 && same(shared_runner, pairs, runner.pairs);
      if (best.support >= 0 && !same_as_best && (runner_same_as_h || best.BetterThan(runner))) {
        std::swap(runner, best);  // the old best becomes the runner-up
      } else if (runner_same_as_h) {
        runner.support = -1;
        runner.pairs = 0;
        std::fill(runner.in.begin(), runner.in.end(), 0);
      }
      static_cast<Hypothesis&>(best) = h;
      best.in = scratch;
      best.pairs = pairs;
      // Adaptive bound (eq. 63-66) with the inlier share found so far.
      const double q = std::pow(best.support / n, 2);
      if (q >= 1.0) {
        bound = 50;
      } else if (q > 0.0) {
        bound = std::max<long>(50, static_cast<long>(std::ceil(std::log(1.0 - o.success_probability) / std::log(1.0 - q))));
      }
    } else if (!same_as_best && h.BetterThan(runner)) {
      static_cast<Hypothesis&>(runner) = h;
      runner.in = scratch;
      runner.pairs = pairs;
    }
  }
  r.iterations = it;
  r.best_support = std::max(0, best.support);
  r.runner_up_support = std::max(0, runner.support);
  if (best.support < 2) {
    r.verdict = AlignmentVerdict::kTooFewInliers;
    return r;
  }

  // Refine on the consensus, then (optionally) gather inliers among all landmarks.
  std::vector<std::tuple<double, int, int>> scored;
  for (const CandidatePair& c : cand) {
    const double d2 = inlier_d2(c, best.t);
    if (std::isfinite(d2)) scored.emplace_back(d2, c.a, c.b);
  }
  Conclude(a_in, b_in, a, b, best.t, OneToOne(std::move(scored)), o, o.guided_matching, r);
  return r;
}

AlignmentResult VerifyAlignment(const LandmarkMap& a_in, const LandmarkMap& b_in, const Pose2& guess,
                                const AlignmentOptions& o) {
  const LandmarkMap a = ForAlignment(a_in, o.min_shape_sigma_m), b = ForAlignment(b_in, o.min_shape_sigma_m);
  AlignmentResult r;
  const Usable ua = UsableLandmarks(a), ub = UsableLandmarks(b);
  r.usable_a = static_cast<int>(ua.points.size());
  r.usable_b = static_cast<int>(ub.points.size());
  if (r.usable_a < 3 || r.usable_b < 3) {
    r.verdict = AlignmentVerdict::kTooFewLandmarks;
    return r;
  }
  Conclude(a_in, b_in, a, b, guess, {}, o, /*guided=*/true, r);
  return r;
}

AlignmentResult AlignMaps(const LandmarkMap& a, const LandmarkMap& b, const AlignmentOptions& o, std::mt19937_64& rng) {
  AlignmentResult stats;
  const std::vector<CandidatePair> cand = MatchTriangles(a, b, o, rng, &stats);
  if (stats.usable_a < 3 || stats.usable_b < 3) {
    stats.verdict = AlignmentVerdict::kTooFewLandmarks;
    return stats;
  }
  if (stats.triangles_a == 0 || stats.triangles_b == 0) {
    stats.verdict = AlignmentVerdict::kNoTriangles;
    return stats;
  }
  AlignmentResult r = RansacAlign(a, b, cand, o, rng);
  r.best_patch = stats.best_patch;
  r.patches = stats.patches;
  r.usable_a = stats.usable_a;
  r.usable_b = stats.usable_b;
  r.triangles_a = stats.triangles_a;
  r.triangles_b = stats.triangles_b;
  return r;
}

}  // namespace mapmesh
