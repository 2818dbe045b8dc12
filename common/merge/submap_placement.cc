#include "common/merge/submap_placement.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <optional>
#include <set>
#include <unordered_map>

#include "common/geometry/rigid_fit.h"
#include "common/merge/point_grid.h"
#include "common/solver/chi2.h"

namespace mapmesh {
namespace {

// A submap's landmarks in its own frame with their marginal covariances (the 2 x 2 diagonal
// blocks of l l^T, from l's rows alone).
LandmarkMap SubmapLandmarks(const WireSubmap& s) {
  LandmarkMap m;
  m.landmarks.reserve(s.keys.size());
  for (std::size_t i = 0; i < s.keys.size(); ++i) {
    const Eigen::Index r = 3 + 2 * static_cast<Eigen::Index>(i);
    const Eigen::MatrixXd rows = s.l.block(r, 0, 2, r + 2);
    Landmark l;
    l.id = s.keys[i];
    l.mean = s.x.segment<2>(r);
    l.cov = rows * rows.transpose();
    m.landmarks.push_back(l);
  }
  return m;
}

struct Fit {
  Pose2 pose;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  int pairs = 0;
};

// Pairs each landmark of `local` (placed at `at`) with the target's nearest, when unique.
std::vector<std::pair<int, int>> Pair(const LandmarkMap& local, const Pose2& at, const LandmarkMap& target,
                                      const PointGrid2& grid, const PiecewiseOptions& o) {
  std::vector<std::pair<int, int>> pairs;
  const PoseMap2 t(at);
  std::set<int> used;
  for (std::size_t i = 0; i < local.landmarks.size(); ++i) {
    const Eigen::Vector2d p = t.Apply(local.landmarks[i].mean);
    int best = -1;
    double d1 = std::numeric_limits<double>::infinity(), d2 = d1;
    grid.Visit(p, o.pair_radius_m * o.unique_ratio, [&](int c) {
      const double d = (target.landmarks[c].mean - p).norm();
      if (d < d1 || (d == d1 && c < best)) {
        d2 = d1;
        d1 = d;
        best = c;
      } else if (d < d2) {
        d2 = d;
      }
      return false;
    });
    if (best < 0 || d1 > o.pair_radius_m || d2 < o.unique_ratio * d1) continue;
    if (!used.insert(best).second) continue;  // two landmarks of one submap are two trees
    pairs.push_back({static_cast<int>(i), best});
  }
  return pairs;
}

// The weighted least-squares placement of `local` on its pairs (Gauss-Newton from the rigid
// fit), its covariance and the residual's chi-square; nullopt when degenerate.
std::optional<Fit> FitPlacement(const LandmarkMap& local, const LandmarkMap& target,
                                const std::vector<std::pair<int, int>>& pairs, double* chi2) {
  std::vector<Eigen::Vector2d> src, dst;
  for (const auto& [i, j] : pairs) {
    src.push_back(local.landmarks[i].mean);
    dst.push_back(target.landmarks[j].mean);
  }
  std::optional<Pose2> pose = FitRigid2D(src, dst);
  if (!pose) return std::nullopt;
  Fit f;
  const double n = static_cast<double>(pairs.size());
  Eigen::Matrix3d h, m;
  for (int it = 0; it < 3; ++it) {
    h.setZero();
    m.setZero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    *chi2 = 0.0;
    const PoseMap2 t(*pose);
    const Eigen::Matrix2d rot = t.Rotation();
    for (const auto& [i, j] : pairs) {
      Eigen::Matrix<double, 2, 3> jac;
      const Eigen::Vector2d r = t.Apply(local.landmarks[i].mean, &jac) - target.landmarks[j].mean;
      const Eigen::Matrix2d c = rot * local.landmarks[i].cov * rot.transpose();
      const Eigen::Matrix2d w = (c + target.landmarks[j].cov).inverse();
      const Eigen::Matrix<double, 3, 2> jw = jac.transpose() * w;
      h += jw * jac;
      g += jw * r;
      m += jw * (c + n * target.landmarks[j].cov) * jw.transpose();
      *chi2 += r.dot(w * r);
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(h);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().array() > 0.0).all()) return std::nullopt;
    const Eigen::Vector3d step = -ldlt.solve(g);
    if (!step.allFinite()) return std::nullopt;
    if (it == 2) break;  // the last pass evaluates the residual and h at the state
    *pose = pose->Retract(step);
  }
  f.pose = *pose;
  // The target's landmarks (one map's) may share their errors: the covariance bounds
  // Cov(sum of n terms) by n times the sum of theirs, whatever their correlation (the residual
  // and the chi-square gate see the pairs' own errors only: a shared error moves the pose).
  const Eigen::Matrix3d h_inv = h.inverse();
  f.cov = h_inv * m * h_inv;
  f.pairs = static_cast<int>(pairs.size());
  return f;
}

// Where a submap's frame lies in its robot's whole map: the rigid fit of its landmarks onto the
// map's of the same keys; nullopt with fewer than three.
std::optional<Pose2> FrameInMap(const LandmarkMap& submap,
                                const std::unordered_map<std::uint32_t, Eigen::Vector2d>& map) {
  std::vector<Eigen::Vector2d> src, dst;
  for (const Landmark& l : submap.landmarks) {
    const auto it = map.find(l.id);
    if (it == map.end()) continue;
    src.push_back(l.mean);
    dst.push_back(it->second);
  }
  if (src.size() < 3) return std::nullopt;
  return FitRigid2D(src, dst);
}

}  // namespace

std::vector<MapSource> PlaceSubmapsPiecewise(const LandmarkMap& target, const MapSource& whole,
                                             std::span<const WireSubmap* const> chain, const PiecewiseOptions& o,
                                             PiecewiseStats* stats) {
  if (chain.empty()) return {whole};
  PiecewiseStats s;
  std::vector<Eigen::Vector2d> points;
  points.reserve(target.size());
  for (const Landmark& l : target.landmarks) points.push_back(l.mean);
  const PointGrid2 grid(points);
  std::unordered_map<std::uint32_t, Eigen::Vector2d> in_whole_map;
  for (const Landmark& l : whole.map.landmarks) in_whole_map.emplace(l.id, l.mean);
  std::vector<MapSource> out;
  std::set<std::uint32_t> held;
  Pose2 at = whole.to_own;
  Eigen::Matrix3d at_cov = whole.to_own_cov;
  // The last fitted submap: its placement and its frame in the whole map.
  std::optional<std::pair<Pose2, Pose2>> anchor;
  for (std::size_t k = 0; k < chain.size(); ++k) {
    const WireSubmap& sub = *chain[k];
    const LandmarkMap sub_map = SubmapLandmarks(sub);
    const std::optional<Pose2> in_whole = FrameInMap(sub_map, in_whole_map);
    if (k > 0) {
      // Along the chain: the previous frame composed with its end pose, the covariance grown by
      // the end pose's ...
      const WireSubmap& prev = *chain[k - 1];
      const Pose2 end{prev.x(0), prev.x(1), prev.x(2)};
      const Eigen::Matrix3d end_cov = prev.l.topLeftCorner(3, 3) * prev.l.topLeftCorner(3, 3).transpose();
      Eigen::Matrix3d ja, jb;
      at = Compose(at, end, &ja, &jb);
      at_cov = ja * at_cov * ja.transpose() + jb * end_cov * jb.transpose();
    }
    // ... where the whole map (the robot's joined estimate, better than the chain alone) puts
    // it relative to the last fitted submap, or at its alignment before any.
    if (in_whole) {
      at = anchor ? anchor->first * anchor->second.Inverse() * *in_whole : whole.to_own * *in_whole;
    }
    MapSource src{whole.robot, whole.incarnation, sub_map, at, at_cov, whole.relayed};
    for (const std::uint32_t key : sub.keys) held.insert(key);
    ++s.submaps;
    // From where the chain puts it, and from where the whole map's alignment does (the submap's
    // frame fitted into the whole map by its keys): the accepted fit with more pairs wins.
    std::optional<Fit> fit;
    bool refused = false;
    const auto try_from = [&](Pose2 from) {
      std::optional<Fit> f;
      bool gated = false;
      for (int it = 0; it < o.iterations; ++it) {
        const std::vector<std::pair<int, int>> pairs = Pair(src.map, from, target, grid, o);
        if (static_cast<int>(pairs.size()) < o.min_pairs) return;
        double chi2 = 0.0;
        f = FitPlacement(src.map, target, pairs, &chi2);
        if (!f) return;
        const int dof = 2 * f->pairs - 3;
        double rms = 0.0;
        const PoseMap2 t(f->pose);
        for (const auto& [i, j] : pairs)
          rms += (t.Apply(src.map.landmarks[i].mean) - target.landmarks[j].mean).squaredNorm();
        rms = std::sqrt(rms / f->pairs);
        gated = (dof > 0 && chi2 > Chi2Quantile(o.gate_probability, dof)) || rms > o.max_rms_m;
        from = f->pose;
      }
      if (gated) {
        refused = refused || !fit;
        return;
      }
      if (!fit || f->pairs > fit->pairs) fit = f;
    };
    try_from(at);
    if (in_whole) try_from(whole.to_own * *in_whole);
    if (fit) refused = false;
    if (fit) {
      if (in_whole) anchor = {fit->pose, *in_whole};
      at = fit->pose;
      at_cov = fit->cov;
      ++s.fitted;
      s.pairs += fit->pairs;
    } else {
      if (refused) ++s.refused;
      ++s.chained;
    }
    src.to_own = at;
    src.to_own_cov = at_cov;
    out.push_back(std::move(src));
  }
  MapSource rest{whole.robot, whole.incarnation, {}, whole.to_own, whole.to_own_cov, whole.relayed};
  for (const Landmark& l : whole.map.landmarks) {
    if (!held.contains(l.id)) rest.map.landmarks.push_back(l);
  }
  s.rest = static_cast<int>(rest.map.size());
  if (!rest.map.landmarks.empty()) out.push_back(std::move(rest));
  if (stats != nullptr) *stats += s;
  return out;
}

}  // namespace mapmesh
