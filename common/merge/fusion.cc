#include "common/merge/fusion.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "common/map/landmark_map.h"
#include "common/merge/robust_covariance.h"

namespace mapmesh {
namespace {

// Along M(t) = m0 + t d (2x2 symmetric), t in [lo, hi] with lo <= 0 <= hi: the t minimising
// det (or trace) of M(t)^-1. det M(t) = d0 + d1 t + d2 t^2 and trace M(t) = t0 + t1 t, so both
// criteria have closed-form stationary points. Ties keep t = 0 (no move), so that inputs that
// are all alike keep equal weights.
double LineOptimum(const Eigen::Matrix2d& m0, const Eigen::Matrix2d& d, double lo, double hi, CiCriterion criterion) {
  const double a = m0(0, 0), b = m0(0, 1), c = m0(1, 1);
  const double p = d(0, 0), q = d(0, 1), r = d(1, 1);
  const double d0 = a * c - b * b, d1 = a * r + c * p - 2.0 * b * q, d2 = p * r - q * q;
  auto det = [&](double t) { return d0 + t * (d1 + t * d2); };
  std::array<double, 5> cand{0.0, lo, hi, 0.0, 0.0};
  int n = 3;
  if (criterion == CiCriterion::kDeterminant) {
    // Maximise det M(t): interior maximum only where the parabola opens downwards.
    if (d2 < 0.0) cand[n++] = std::clamp(-d1 / (2.0 * d2), lo, hi);
    double best = 0.0, best_det = det(0.0);
    for (int k = 1; k < n; ++k) {
      if (det(cand[k]) > best_det) {
        best_det = det(cand[k]);
        best = cand[k];
      }
    }
    return best;
  }
  // Minimise (t0 + t1 t) / det(t): stationary where
  // -t1 d2 t^2 - 2 t0 d2 t + (t1 d0 - t0 d1) = 0.
  const double t0 = a + c, t1 = p + r;
  const double qa = -t1 * d2, qb = -2.0 * t0 * d2, qc = t1 * d0 - t0 * d1;
  const double scale = std::max({std::abs(qa), std::abs(qb), std::abs(qc), 1e-300});
  if (std::abs(qa) <= 1e-14 * scale) {
    if (std::abs(qb) > 1e-14 * scale) cand[n++] = std::clamp(-qc / qb, lo, hi);
  } else {
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc >= 0.0) {
      // Numerically stable roots.
      const double s = -0.5 * (qb + std::copysign(std::sqrt(disc), qb));
      cand[n++] = std::clamp(s / qa, lo, hi);
      if (s != 0.0) cand[n++] = std::clamp(qc / s, lo, hi);
    }
  }
  double best = 0.0, best_f = (t0) / det(0.0);
  for (int k = 1; k < n; ++k) {
    const double dt = det(cand[k]);
    if (!(dt > 0.0)) continue;
    const double f = (t0 + t1 * cand[k]) / dt;
    if (f < best_f) {
      best_f = f;
      best = cand[k];
    }
  }
  return best;
}

// Information form of a valid estimate.
Eigen::Matrix2d Info(const Eigen::Matrix2d& cov) { return cov.inverse(); }

constexpr int kMaxSweeps = 100;

Eigen::Matrix2d Symmetric(const Eigen::Matrix2d& m) { return 0.5 * (m + m.transpose()); }

constexpr int kPatternRings = 16, kPatternAngles = 16;

std::vector<Eigen::Vector2d> MakeOgkPattern() {
  // Ring m holds the chi2_2 probability slice [m/M, (m+1)/M); its squared radius is the slice's
  // mean of chi2_2, M * (G(t_b) - G(t_a)) with G(t) = int_0^t x dF = 2 - (t + 2) e^(-t/2).
  const auto g = [](double t) { return 2.0 - (t + 2.0) * std::exp(-0.5 * t); };
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  std::vector<Eigen::Vector2d> out;
  out.reserve(kPatternRings * kPatternAngles);
  for (int m = 0; m < kPatternRings; ++m) {
    const double ta = -2.0 * std::log1p(-static_cast<double>(m) / kPatternRings);
    const double gb = m + 1 == kPatternRings ? 2.0 : g(-2.0 * std::log1p(-static_cast<double>(m + 1) / kPatternRings));
    const double r = std::sqrt(kPatternRings * (gb - g(ta)));
    const double phase = std::fmod(m * golden, 1.0);
    for (int k = 0; k < kPatternAngles; ++k) {
      const double a = 2.0 * std::numbers::pi * (k + phase) / kPatternAngles;
      out.emplace_back(r * std::cos(a), r * std::sin(a));
    }
  }
  return out;
}

// OGK's scatter of the pattern itself is c I (its 16-fold symmetry); c calibrates the fusion.
double OgkPatternScale() {
  static const double c = [] {
    const std::optional<OgkEstimate> e = Ogk(OgkFusionPattern());
    return e ? 0.5 * e->scatter.trace() : 1.0;
  }();
  return c;
}

// Symmetric square root of a valid covariance.
Eigen::Matrix2d SqrtCov(const Eigen::Matrix2d& c) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(c);
  return es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
}

// OGK fusion of valid inputs (fusion.h); nullopt only if OGK fails, which the quasi-samples of
// invertible covariances do not let happen.
std::optional<Gaussian2> FuseOgk(std::span<const Gaussian2> in) {
  const std::vector<Eigen::Vector2d>& pattern = OgkFusionPattern();
  std::vector<Eigen::Vector2d> points;
  points.reserve(in.size() * pattern.size());
  for (const Gaussian2& g : in) {
    const Eigen::Matrix2d s = SqrtCov(g.cov);
    for (const Eigen::Vector2d& q : pattern) points.push_back(g.mean + s * q);
  }
  const std::optional<OgkEstimate> e = Ogk(points);
  if (!e) return std::nullopt;
  return Gaussian2{e->location, Symmetric(e->scatter / OgkPatternScale())};
}

}  // namespace

const std::vector<Eigen::Vector2d>& OgkFusionPattern() {
  static const std::vector<Eigen::Vector2d> pattern = MakeOgkPattern();
  return pattern;
}

FusionVerdict CheckEstimate(const Gaussian2& g) {
  if (!g.mean.allFinite()) return FusionVerdict::kNonFiniteMean;
  if (!IsValidCovariance(g.cov)) return FusionVerdict::kInvalidCovariance;
  // Invertible with a sane condition: det well above rounding relative to the scale.
  const double scale = std::max(std::abs(g.cov(0, 0)), std::abs(g.cov(1, 1)));
  const double det = g.cov(0, 0) * g.cov(1, 1) - g.cov(0, 1) * g.cov(1, 0);
  if (!(scale > 0.0) || !(det > 1e-12 * scale * scale)) return FusionVerdict::kSingularCovariance;
  return FusionVerdict::kFused;
}

FusionResult Fuse(std::span<const Gaussian2> in, FusionMethod method) {
  FusionResult r;
  if (in.empty()) return r;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const FusionVerdict v = CheckEstimate(in[i]);
    if (v != FusionVerdict::kFused) {
      r.verdict = v;
      r.bad_input = static_cast<int>(i);
      return r;
    }
  }
  r.verdict = FusionVerdict::kFused;
  const std::size_t n = in.size();
  if (n == 1) {
    r.fused = in[0];
    r.weights = {1.0};
    return r;
  }
  if (method == FusionMethod::kOgk || method == FusionMethod::kCiOgk) {
    FusionResult ci = Fuse(in, FusionMethod::kCiConstant);
    const std::optional<Gaussian2> ogk = FuseOgk(in);
    // OGK cannot fail on valid inputs (see FuseOgk); CI stands in if it ever did.
    if (!ogk) return ci;
    if (method == FusionMethod::kCiOgk && ci.fused.cov.determinant() <= ogk->cov.determinant()) return ci;
    r.fused = *ogk;
    return r;
  }
  if (method == FusionMethod::kMaximumLikelihood) {
    Eigen::Vector2d mu = Eigen::Vector2d::Zero();
    for (const Gaussian2& g : in) mu += g.mean;
    mu /= static_cast<double>(n);
    Eigen::Matrix2d c = Eigen::Matrix2d::Zero();
    for (const Gaussian2& g : in) c += (g.mean - mu) * (g.mean - mu).transpose();
    r.fused = {mu, c / static_cast<double>(n)};
    return r;
  }
  std::vector<Eigen::Matrix2d> info(n);
  for (std::size_t i = 0; i < n; ++i) info[i] = Info(in[i].cov);
  std::vector<double> w(n, method == FusionMethod::kInformation ? 1.0 : 1.0 / static_cast<double>(n));
  if (method == FusionMethod::kCiDeterminant || method == FusionMethod::kCiTrace) {
    const CiCriterion crit = method == FusionMethod::kCiDeterminant ? CiCriterion::kDeterminant : CiCriterion::kTrace;
    // Exact pairwise exchanges of weight (one exchange is the optimum for two inputs).
    Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
    for (std::size_t i = 0; i < n; ++i) m += w[i] * info[i];
    for (int sweep = 0; sweep < kMaxSweeps; ++sweep) {
      double moved = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        for (std::size_t j = i + 1; j < n; ++j) {
          // Move t from j to i: w_i + t, w_j - t, t in [-w_i, w_j].
          const Eigen::Matrix2d d = info[i] - info[j];
          const double t = LineOptimum(m, d, -w[i], w[j], crit);
          if (t == 0.0) continue;
          w[i] += t;
          w[j] -= t;
          m += t * d;
          moved = std::max(moved, std::abs(t));
        }
      }
      if (n == 2 || moved < 1e-13) break;
    }
  }
  Eigen::Matrix2d total = Eigen::Matrix2d::Zero();
  Eigen::Vector2d eta = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    total += w[i] * info[i];
    eta += w[i] * (info[i] * in[i].mean);
  }
  const Eigen::Matrix2d cov = Symmetric(total.inverse());
  r.fused = {cov * eta, cov};
  if (method != FusionMethod::kInformation) r.weights = std::move(w);
  return r;
}

namespace {

Gaussian2 FuseInformation(const Gaussian2& a, const Gaussian2& b, const Eigen::Matrix2d& ia, const Eigen::Matrix2d& ib,
                          double w) {
  const Eigen::Matrix2d cov = Symmetric((w * ia + (1.0 - w) * ib).inverse());
  return {cov * (w * (ia * a.mean) + (1.0 - w) * (ib * b.mean)), cov};
}

}  // namespace

Gaussian2 CiFuseWithWeight(const Gaussian2& a, const Gaussian2& b, double w) {
  return FuseInformation(a, b, a.cov.inverse(), b.cov.inverse(), w);
}

std::optional<Gaussian2> FusePair(const Gaussian2& a, const Gaussian2& b, FusionMethod method, double* weight) {
  if (CheckEstimate(a) != FusionVerdict::kFused || CheckEstimate(b) != FusionVerdict::kFused) return std::nullopt;
  if (method == FusionMethod::kOgk || method == FusionMethod::kCiOgk) {
    const std::array<Gaussian2, 2> in{a, b};
    const FusionResult r = Fuse(in, method);
    if (weight && !r.weights.empty()) *weight = r.weights[0];
    return r.fused;
  }
  if (method == FusionMethod::kMaximumLikelihood) {
    const Eigen::Vector2d mu = 0.5 * (a.mean + b.mean), d = 0.5 * (a.mean - b.mean);
    return Gaussian2{mu, d * d.transpose()};
  }
  const Eigen::Matrix2d ia = a.cov.inverse(), ib = b.cov.inverse();
  if (method == FusionMethod::kInformation) {
    const Eigen::Matrix2d cov = Symmetric((ia + ib).inverse());
    return Gaussian2{cov * (ia * a.mean + ib * b.mean), cov};
  }
  double w = 0.5;
  if (method != FusionMethod::kCiConstant && method != FusionMethod::kJoining) {
    const CiCriterion c = method == FusionMethod::kCiDeterminant ? CiCriterion::kDeterminant : CiCriterion::kTrace;
    w = 0.5 + LineOptimum(0.5 * (ia + ib), ia - ib, -0.5, 0.5, c);
  }
  if (weight) *weight = w;
  return FuseInformation(a, b, ia, ib, w);
}

double CiWeight(const Eigen::Matrix2d& a, const Eigen::Matrix2d& b, CiCriterion criterion) {
  // From equal weights, move t in [-1/2, 1/2] of weight onto a.
  return 0.5 + LineOptimum(0.5 * (a + b), a - b, -0.5, 0.5, criterion);
}

double CiWeightBySearch(const Eigen::Matrix2d& a, const Eigen::Matrix2d& b, CiCriterion criterion, double tol) {
  auto cost = [&](double w) {
    const Eigen::Matrix2d cov = (w * a + (1.0 - w) * b).inverse();
    return criterion == CiCriterion::kDeterminant ? cov.determinant() : cov.trace();
  };
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double lo = 0.0, hi = 1.0;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = cost(x1), f2 = cost(x2);
  while (hi - lo > tol) {
    if (f1 < f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - g * (hi - lo);
      f1 = cost(x1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + g * (hi - lo);
      f2 = cost(x2);
    }
  }
  // The ends are candidates too (the optimum is often on the boundary).
  const double mid = 0.5 * (lo + hi);
  double best = mid, best_f = cost(mid);
  for (double e : {0.0, 1.0}) {
    if (cost(e) < best_f) {
      best_f = cost(e);
      best = e;
    }
  }
  return best;
}

}  // namespace mapmesh
