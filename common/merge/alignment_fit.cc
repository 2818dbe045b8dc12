#include "common/merge/alignment_fit.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "common/merge/point_grid.h"
#include "common/solver/chi2.h"

namespace mapmesh::alignment_detail {
namespace {

// The information matrix of (x, y, theta) from the pairs at t, and the gradient of the
// weighted squared residuals.
Eigen::Matrix3d Information(const LandmarkMap& a, const LandmarkMap& b, const std::vector<std::pair<int, int>>& pairs,
                            const Pose2& t, Eigen::Vector3d* gradient) {
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  Eigen::Vector3d g = Eigen::Vector3d::Zero();
  const PoseMap2 tm(t);
  const Eigen::Matrix2d rot = tm.Rotation();
  for (const auto& [ia, ib] : pairs) {
    const Landmark &la = a.landmarks[ia], &lb = b.landmarks[ib];
    Eigen::Matrix<double, 2, 3> j_apply;
    const Eigen::Vector2d r = la.mean - tm.Apply(lb.mean, &j_apply);
    const Eigen::Matrix2d c = la.cov + rot * lb.cov * rot.transpose();
    const Eigen::LDLT<Eigen::Matrix2d> ldlt(c);
    if (ldlt.info() != Eigen::Success || !(c.determinant() > 0)) continue;
    const Eigen::Matrix<double, 2, 3> j = -j_apply;  // of the residual
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
    *t = t->Retract(step);
    if (step.head<2>().norm() < 1e-9 && std::abs(step(2)) < 1e-12) break;
  }
  return info;
}

}  // namespace

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

double PairD2(const Landmark& la, const Landmark& lb, const PoseMap2& t, Eigen::Vector2d* r) {
  const Eigen::Matrix2d rot = t.Rotation();
  const Eigen::Vector2d res = la.mean - t.Apply(lb.mean);
  const Eigen::Matrix2d c = la.cov + rot * lb.cov * rot.transpose();
  if (r) *r = res;
  const double det = c.determinant();
  if (!(det > 0.0)) return std::numeric_limits<double>::infinity();
  return res.dot(c.inverse() * res);
}

LandmarkMap ForAlignment(const LandmarkMap& m, double floor_m, bool every_landmark) {
  if (!(m.shape_sigma_m > 0.0) || !std::isfinite(m.shape_sigma_m)) return m;
  LandmarkMap out = m;
  const double s = std::max(m.shape_sigma_m, floor_m), v = s * s;
  for (Landmark& l : out.landmarks) {
    if (l.mean.allFinite() && IsValidCovariance(l.cov) &&
        (every_landmark || LargestSigma(l.cov) * LargestSigma(l.cov) > v)) {
      l.cov = v * Eigen::Matrix2d::Identity();
    }
  }
  return out;
}

std::vector<std::pair<int, int>> OneToOne(std::vector<std::tuple<double, int, int>> scored) {
  std::sort(scored.begin(), scored.end());
  int na = 0, nb = 0;
  for (const auto& [d2, ia, ib] : scored) {
    na = std::max(na, ia + 1);
    nb = std::max(nb, ib + 1);
  }
  std::vector<char> used_a(na, 0), used_b(nb, 0);
  std::vector<std::pair<int, int>> out;
  for (const auto& [d2, ia, ib] : scored) {
    if (used_a[ia] || used_b[ib]) continue;
    used_a[ia] = used_b[ib] = 1;
    out.emplace_back(ia, ib);
  }
  return out;
}

double GatedD2(const Landmark& la, const Landmark& lb, const PoseMap2& t, const AlignmentOptions& o, double gate) {
  if (o.distance == ConsensusDistance::kEuclidean) {
    const double e = (la.mean - t.Apply(lb.mean)).norm();
    return e < o.euclidean_gate_m ? e * e : std::numeric_limits<double>::infinity();
  }
  const double d2 = PairD2(la, lb, t);
  return d2 < gate ? d2 : std::numeric_limits<double>::infinity();
}

ConsensusScorer::ConsensusScorer(const LandmarkMap& a, const LandmarkMap& b, const std::vector<CandidatePair>& cand,
                                 const AlignmentOptions& o)
    : a_(a),
      b_(b),
      cand_(cand),
      o_(o),
      gate_(Chi2Quantile(o.gate_probability, 2)),
      stamp_a_(a.landmarks.size(), -1),
      stamp_b_(b.landmarks.size(), -1) {}

ConsensusScorer::Score ConsensusScorer::Evaluate(const PoseMap2& t, std::vector<char>& in) {
  Score s;
  int na = 0, nb = 0;
  ++evaluation_;
  in.resize(cand_.size());
  for (std::size_t i = 0; i < cand_.size(); ++i) {
    const CandidatePair& c = cand_[i];
    const double d2 = GatedD2(a_.landmarks[c.a], b_.landmarks[c.b], t, o_, gate_);
    in[i] = std::isfinite(d2);
    if (!in[i]) continue;
    ++s.pairs;
    if (stamp_a_[c.a] != evaluation_) {
      stamp_a_[c.a] = evaluation_;
      ++na;
    }
    if (stamp_b_[c.b] != evaluation_) {
      stamp_b_[c.b] = evaluation_;
      ++nb;
    }
    s.cost += d2;
  }
  s.support = std::min(na, nb);
  return s;
}

std::vector<std::pair<int, int>> GatedPairs(const LandmarkMap& a, const Usable& ua, const PointGrid2& grid,
                                            const LandmarkMap& b, const Usable& ub, const Pose2& t,
                                            const AlignmentOptions& o, double* cost) {
  const double gate = Chi2Quantile(o.gate_probability, 2);
  std::vector<std::tuple<double, int, int>> scored;
  const double radius_scale = o.distance == ConsensusDistance::kEuclidean ? 0.0 : std::sqrt(gate);
  const PoseMap2 tm(t);
  for (std::size_t j = 0; j < ub.points.size(); ++j) {
    const Eigen::Vector2d p = tm.Apply(ub.points[j]);
    const double radius = o.distance == ConsensusDistance::kEuclidean
                              ? o.euclidean_gate_m
                              : radius_scale * std::sqrt(ua.max_sigma * ua.max_sigma + ub.sigma[j] * ub.sigma[j]);
    grid.Visit(p, radius, [&](int i) {
      const double d2 = GatedD2(a.landmarks[ua.index[i]], b.landmarks[ub.index[j]], tm, o, gate);
      if (std::isfinite(d2)) scored.emplace_back(d2, ua.index[i], ub.index[j]);
      return false;
    });
  }
  std::vector<std::pair<int, int>> pairs = OneToOne(scored);
  if (cost) {
    // The cost of the pairs kept: OneToOne sorted nothing in scored, so look each one up.
    std::sort(scored.begin(), scored.end());
    *cost = 0.0;
    std::size_t k = 0;
    for (const auto& [d2, ia, ib] : scored) {
      if (k < pairs.size() && pairs[k] == std::pair<int, int>(ia, ib)) {
        *cost += d2;
        ++k;
      }
    }
  }
  return pairs;
}

void Conclude(const LandmarkMap& a_in, const LandmarkMap& b_in, const LandmarkMap& a, const LandmarkMap& b, Pose2 t,
              std::vector<std::pair<int, int>> inliers, const AlignmentOptions& o, bool guided, AlignmentResult& r) {
  const LandmarkMap fit_a = ForAlignment(a_in, o.min_shape_sigma_m, /*every_landmark=*/true);
  const LandmarkMap fit_b = ForAlignment(b_in, o.min_shape_sigma_m, /*every_landmark=*/true);
  if (!inliers.empty()) Refine(fit_a, fit_b, inliers, &t);
  if (guided) {
    const Usable ua = UsableLandmarks(a), ub = UsableLandmarks(b);
    if (!ua.points.empty() && !ub.points.empty()) {
      const PointGrid2 grid(ua.points);
      for (int round = 0; round < 2; ++round) {
        inliers = GatedPairs(a, ua, grid, b, ub, t, o);
        Refine(fit_a, fit_b, inliers, &t);
      }
    }
  }

  // Where the transform lays B over ground A has mapped, B's landmarks should find partners.
  {
    const Usable ua = UsableLandmarks(a), ub = UsableLandmarks(b);
    if (!ua.points.empty()) {
      const PointGrid2 grid(ua.points);
      const PoseMap2 tm(t);
      for (const Eigen::Vector2d& p : ub.points) {
        if (grid.AnyInRadius(tm.Apply(p), o.coverage_radius_m)) ++r.covered;
      }
    }
  }
  r.transform = t;
  r.inliers = inliers;
  const PoseMap2 tm(t);
  for (const auto& [ia, ib] : inliers) r.residual_chi2 += PairD2(a.landmarks[ia], b.landmarks[ib], tm);
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
  // 2 residual dimensions per inlier, 3 parameters fitted: chi-square with 2n - 3 dof bounds
  // the sum.
  r.residual_bound = o.residual_tolerance * Chi2Quantile(o.residual_probability, std::max(1, 2 * ni - 3));
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

}  // namespace mapmesh::alignment_detail
