#include "common/merge/rendezvous.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "common/geometry/rigid_fit.h"
#include "common/solver/chi2.h"

namespace mapmesh {

std::optional<RendezvousResult> RendezvousAlign(const RendezvousInput& in) {
  const double values[] = {in.pose1.x,     in.pose1.y, in.pose1.theta, in.pose2.x, in.pose2.y,
                           in.pose2.theta, in.range12, in.bearing12,   in.range21, in.bearing21};
  for (double v : values) {
    if (!std::isfinite(v)) return std::nullopt;
  }
  if (!(in.sigma_range1 > 0 && in.sigma_range2 > 0) || !in.cov1.allFinite() || !in.cov2.allFinite())
    return std::nullopt;
  RendezvousResult r;
  // Eq. 40: inverse-variance mean of the two ranges.
  const double w1 = 1.0 / (in.sigma_range1 * in.sigma_range1), w2 = 1.0 / (in.sigma_range2 * in.sigma_range2);
  r.range = (w1 * in.range12 + w2 * in.range21) / (w1 + w2);
  r.range_disagreement = std::abs(in.range12 - in.range21) /
                         std::sqrt(in.sigma_range1 * in.sigma_range1 + in.sigma_range2 * in.sigma_range2);
  // Eq. 42-44: robot 2 in robot 1's frame.
  const double c = std::cos(in.bearing12), s = std::sin(in.bearing12);
  const Pose2 rel{r.range * c, r.range * s, WrapAngle(M_PI + in.bearing12 - in.bearing21)};
  // Eq. 45-50: frame 2 -> frame 1 is pose1 * rel * pose2^-1.
  Eigen::Matrix3d j_p1, j_rel, j_m, j_inv2, j_inv;
  const Pose2 in1 = Compose(in.pose1, rel, &j_p1, &j_rel);
  const Pose2 inv2 = Invert(in.pose2, &j_inv2);
  r.transform = Compose(in1, inv2, &j_m, &j_inv);
  // Jacobians of rel with respect to (range12, bearing12, range21, bearing21).
  Eigen::Matrix<double, 3, 4> j_z;
  const double dr1 = w1 / (w1 + w2), dr2 = w2 / (w1 + w2);
  j_z << dr1 * c, -r.range * s, dr2 * c, 0,  //
      dr1 * s, r.range * c, dr2 * s, 0,      //
      0, 1, 0, -1;
  const Eigen::Vector4d z_var(in.sigma_range1 * in.sigma_range1, in.sigma_bearing1 * in.sigma_bearing1,
                              in.sigma_range2 * in.sigma_range2, in.sigma_bearing2 * in.sigma_bearing2);
  const Eigen::Matrix3d a1 = j_m * j_p1, a_rel = j_m * j_rel, a2 = j_inv * j_inv2;
  const Eigen::Matrix<double, 3, 4> a_z = a_rel * j_z;
  r.cov = a1 * in.cov1 * a1.transpose() + a2 * in.cov2 * a2.transpose() + a_z * z_var.asDiagonal() * a_z.transpose();
  r.cov = 0.5 * (r.cov + r.cov.transpose()).eval();
  return r;
}

double TransformDistance2(const Pose2& a, const Eigen::Matrix3d& cov_a, const Pose2& b, const Eigen::Matrix3d& cov_b) {
  const Eigen::Vector3d d(a.x - b.x, a.y - b.y, WrapAngle(a.theta - b.theta));
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(cov_a + cov_b);
  if (!d.allFinite() || ldlt.info() != Eigen::Success || !ldlt.isPositive())
    return std::numeric_limits<double>::infinity();
  return d.dot(ldlt.solve(d));
}

std::string_view ToString(RendezvousVerdict v) {
  switch (v) {
    case RendezvousVerdict::kAccepted: return "accepted";
    case RendezvousVerdict::kTooFewSightings: return "too_few_sightings";
    case RendezvousVerdict::kNoBaseline: return "no_baseline";
    case RendezvousVerdict::kTooFewInliers: return "too_few_inliers";
    case RendezvousVerdict::kResidualsTooLarge: return "residuals_too_large";
    case RendezvousVerdict::kDegenerate: return "degenerate";
  }
  return "unknown";
}

std::optional<PointEstimate> SightedPosition(const Pose2& observer, const Eigen::Matrix3d& observer_cov, double range,
                                             double bearing, double sigma_range, double sigma_bearing) {
  const double values[] = {observer.x, observer.y, observer.theta, range, bearing, sigma_range, sigma_bearing};
  for (double v : values) {
    if (!std::isfinite(v)) return std::nullopt;
  }
  if (!observer_cov.allFinite() || !(sigma_range > 0) || !(sigma_bearing > 0) || range < 0) return std::nullopt;
  const double a = observer.theta + bearing, c = std::cos(a), s = std::sin(a);
  PointEstimate p;
  p.mean = {observer.x + range * c, observer.y + range * s};
  Eigen::Matrix<double, 2, 3> j_pose;
  j_pose << 1, 0, -range * s, 0, 1, range * c;
  Eigen::Matrix2d j_z;
  j_z << c, -range * s, s, range * c;
  const Eigen::Vector2d z_var(sigma_range * sigma_range, sigma_bearing * sigma_bearing);
  p.cov = j_pose * observer_cov * j_pose.transpose() + j_z * z_var.asDiagonal() * j_z.transpose();
  p.cov = 0.5 * (p.cov + p.cov.transpose()).eval();
  return p;
}

namespace {

bool Valid(const PointEstimate& p) {
  if (!p.mean.allFinite() || !p.cov.allFinite()) return false;
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(p.cov);
  return ldlt.info() == Eigen::Success && ldlt.isPositive() && p.cov.determinant() > 0;
}

bool Valid(const RendezvousResult& m) {
  if (!std::isfinite(m.transform.x) || !std::isfinite(m.transform.y) || !std::isfinite(m.transform.theta) ||
      !m.cov.allFinite())
    return false;
  return Eigen::FullPivLU<Eigen::Matrix3d>(m.cov).isInvertible() && m.cov.determinant() > 0;
}

// One constraint on the transform, linearised at t: residual e (observed minus predicted), its
// Jacobian with respect to t (of the prediction) and its information.
struct Linearised {
  Eigen::Vector3d e = Eigen::Vector3d::Zero();
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d w = Eigen::Matrix3d::Zero();
  int rows = 2;
  double D2() const { return e.head(rows).dot(w.topLeftCorner(rows, rows) * e.head(rows)); }
};

Linearised Linearise(const SightingPair& p, const PoseMap2& t) {
  Linearised l;
  Eigen::Matrix<double, 2, 3> j;
  l.e.head<2>() = p.own.mean - t.Apply(p.peer.mean, &j);
  l.a.topRows<2>() = j;
  const Eigen::Matrix2d r = t.Rotation();
  const Eigen::Matrix2d s = p.own.cov + r * p.peer.cov * r.transpose();
  l.w.topLeftCorner<2, 2>() = s.inverse();
  return l;
}

Linearised Linearise(const RendezvousResult& m, const Pose2& t) {
  Linearised l;
  l.rows = 3;
  l.e = Eigen::Vector3d(m.transform.x - t.x, m.transform.y - t.y, WrapAngle(m.transform.theta - t.theta));
  l.a = Eigen::Matrix3d::Identity();
  l.w = m.cov.inverse();
  return l;
}

struct Consensus {
  std::vector<int> pairs, mutual;
  double d2 = 0.0;
  int Support() const { return static_cast<int>(pairs.size() + 2 * mutual.size()); }
};

Consensus Agreeing(std::span<const SightingPair> pairs, std::span<const RendezvousResult> mutual, const Pose2& t,
                   double gate2, double gate3) {
  Consensus c;
  const PoseMap2 tm(t);
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const double d2 = Linearise(pairs[i], tm).D2();
    if (d2 <= gate2) {
      c.pairs.push_back(static_cast<int>(i));
      c.d2 += d2;
    }
  }
  for (std::size_t i = 0; i < mutual.size(); ++i) {
    const double d2 = Linearise(mutual[i], t).D2();
    if (d2 <= gate3) {
      c.mutual.push_back(static_cast<int>(i));
      c.d2 += d2;
    }
  }
  return c;
}

// Gauss-Newton on the consensus; the information matrix of the last step in *info.
Pose2 Refine(std::span<const SightingPair> pairs, std::span<const RendezvousResult> mutual, const Consensus& c, Pose2 t,
             Eigen::Matrix3d* info) {
  for (int iter = 0; iter < 10; ++iter) {
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    const PoseMap2 tm(t);
    auto add = [&](const Linearised& l) {
      h += l.a.transpose() * l.w * l.a;
      g += l.a.transpose() * l.w * l.e;
    };
    for (int i : c.pairs) add(Linearise(pairs[i], tm));
    for (int i : c.mutual) add(Linearise(mutual[i], t));
    *info = h;
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(h);
    if (!lu.isInvertible()) return t;
    const Eigen::Vector3d d = lu.solve(g);
    t = t.Retract(d);
    if (d.head<2>().norm() < 1e-9 && std::abs(d(2)) < 1e-12) break;
  }
  return t;
}

}  // namespace

RendezvousFit FitRendezvous(std::span<const SightingPair> pairs_in, std::span<const RendezvousResult> mutual_in,
                            const RendezvousFitOptions& o) {
  RendezvousFit fit;
  std::vector<SightingPair> pairs;
  std::vector<RendezvousResult> mutual;
  for (const SightingPair& p : pairs_in) {
    if (Valid(p.own) && Valid(p.peer)) pairs.push_back(p);
  }
  for (const RendezvousResult& m : mutual_in) {
    if (Valid(m)) mutual.push_back(m);
  }
  fit.pairs = static_cast<int>(pairs.size());
  fit.mutual = static_cast<int>(mutual.size());
  const int sightings = fit.pairs + 2 * fit.mutual;
  if (sightings < o.min_sightings) return fit;
  const double gate2 = Chi2Quantile(o.gate_probability, 2), gate3 = Chi2Quantile(o.gate_probability, 3);

  // Hypotheses: every mutual rendezvous, every two sightings far enough apart.
  std::vector<Pose2> hypotheses;
  for (const RendezvousResult& m : mutual) hypotheses.push_back(m.transform);
  const double min_d2 = o.min_baseline_m * o.min_baseline_m;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    for (std::size_t j = i + 1; j < pairs.size(); ++j) {
      if ((pairs[i].peer.mean - pairs[j].peer.mean).squaredNorm() < min_d2) continue;
      if (auto t = FitRigid2D(pairs[i].peer.mean, pairs[j].peer.mean, pairs[i].own.mean, pairs[j].own.mean))
        hypotheses.push_back(*t);
    }
  }
  if (hypotheses.empty()) {
    fit.verdict = RendezvousVerdict::kNoBaseline;
    return fit;
  }
  Consensus best;
  Pose2 best_t;
  for (const Pose2& t : hypotheses) {
    Consensus c = Agreeing(pairs, mutual, t, gate2, gate3);
    if (c.Support() > best.Support() || (c.Support() == best.Support() && c.d2 < best.d2)) {
      best = std::move(c);
      best_t = t;
    }
  }
  // Refine on the consensus, gather it again at the refined transform, refine once more.
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  Pose2 t = best_t;
  if (best.Support() >= 2) {
    t = Refine(pairs, mutual, best, t, &info);
    Consensus again = Agreeing(pairs, mutual, t, gate2, gate3);
    if (again.Support() >= best.Support()) best = std::move(again);
    t = Refine(pairs, mutual, best, t, &info);
  }
  fit.transform = t;
  fit.inlier_pairs = static_cast<int>(best.pairs.size());
  fit.inlier_mutual = static_cast<int>(best.mutual.size());
  const int support = best.Support();
  if (support < o.min_sightings || support < o.min_inlier_share * sightings) {
    fit.verdict = RendezvousVerdict::kTooFewInliers;
    return fit;
  }
  // The rotation must be fixed by the inliers themselves.
  bool baseline = !best.mutual.empty();
  for (std::size_t i = 0; i < best.pairs.size() && !baseline; ++i) {
    for (std::size_t j = i + 1; j < best.pairs.size() && !baseline; ++j) {
      baseline = (pairs[best.pairs[i]].peer.mean - pairs[best.pairs[j]].peer.mean).squaredNorm() >= min_d2;
    }
  }
  if (!baseline) {
    fit.verdict = RendezvousVerdict::kNoBaseline;
    return fit;
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(info);
  if (!lu.isInvertible() || lu.rcond() < 1e-12) {
    fit.verdict = RendezvousVerdict::kDegenerate;
    return fit;
  }
  const PoseMap2 tm(t);
  for (int i : best.pairs) fit.residual_chi2 += Linearise(pairs[i], tm).D2();
  for (int i : best.mutual) fit.residual_chi2 += Linearise(mutual[i], t).D2();
  const int dof = 2 * fit.inlier_pairs + 3 * fit.inlier_mutual - 3;
  fit.residual_bound = o.residual_tolerance * Chi2Quantile(o.residual_probability, std::max(1, dof));
  // Covariance Intersection of the inliers with equal weights: the average information.
  const double groups = static_cast<double>(fit.inlier_pairs + fit.inlier_mutual);
  fit.cov = groups * info.inverse();
  fit.cov = 0.5 * (fit.cov + fit.cov.transpose()).eval();
  if (!std::isfinite(fit.residual_chi2) || fit.residual_chi2 > fit.residual_bound) {
    fit.verdict = RendezvousVerdict::kResidualsTooLarge;
    return fit;
  }
  fit.verdict = RendezvousVerdict::kAccepted;
  return fit;
}

}  // namespace mapmesh
