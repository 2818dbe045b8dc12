#include "common/merge/robust_covariance.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace mapmesh {
namespace {

// Phi^-1(3/4): the MAD of the standard normal.
constexpr double kMadOfNormal = 0.6744897501960817;

// Median of v (reorders v); v not empty.
double Median(std::vector<double>& v) {
  const std::size_t h = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h), v.end());
  const double upper = v[h];
  if (v.size() % 2 == 1) return upper;
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(h)));
}

// E[min(X^2, b^2)] for X ~ N(0, 1) (robustbase's Erho).
double TruncatedSecondMoment(double b) {
  const double cdf = 0.5 * std::erfc(-b / std::numbers::sqrt2);
  const double pdf = std::exp(-0.5 * b * b) / std::sqrt(2.0 * std::numbers::pi);
  return 2.0 * ((1.0 - b * b) * cdf - b * pdf + b * b) - 1.0;
}

// Median and raw MAD of x; nullopt when x is empty.
std::optional<std::pair<double, double>> MedianAndMad(std::span<const double> x) {
  if (x.empty()) return std::nullopt;
  std::vector<double> v(x.begin(), x.end());
  const double med = Median(v);
  for (double& d : v) d = std::abs(d - med);
  return std::pair{med, Median(v)};
}

std::optional<LocationScale> Scale(std::span<const double> x, RobustScale s) {
  return s == RobustScale::kTau ? TauLocationScale(x) : MadLocationScale(x);
}

}  // namespace

std::optional<LocationScale> MadLocationScale(std::span<const double> x) {
  const auto mm = MedianAndMad(x);
  if (!mm) return std::nullopt;
  return LocationScale{mm->first, mm->second / kMadOfNormal};
}

std::optional<LocationScale> TauLocationScale(std::span<const double> x, double c1, double c2) {
  const auto mm = MedianAndMad(x);
  if (!mm || !(mm->second > 0.0)) return std::nullopt;
  const auto [med, s0] = *mm;
  double sw = 0.0, swx = 0.0;
  for (double xi : x) {
    const double u = (xi - med) / (c1 * s0);
    const double w = std::abs(u) <= 1.0 ? (1.0 - u * u) * (1.0 - u * u) : 0.0;
    sw += w;
    swx += w * xi;
  }
  const double mu = swx / sw;  // sw > 0: the points within s0 of the median have weight > 0
  double rho = 0.0;
  for (double xi : x) rho += std::min(((xi - mu) / s0) * ((xi - mu) / s0), c2 * c2);
  const double normal = TruncatedSecondMoment(c2 * kMadOfNormal);
  return LocationScale{mu, s0 * std::sqrt(rho / (static_cast<double>(x.size()) * normal))};
}

std::optional<OgkEstimate> Ogk(std::span<const Eigen::Vector2d> points, const OgkOptions& o) {
  const std::size_t n = points.size();
  if (n < 3 || o.iterations < 1) return std::nullopt;
  for (const Eigen::Vector2d& p : points) {
    if (!p.allFinite()) return std::nullopt;
  }
  std::vector<double> z1(n), z2(n), sum(n), diff(n);
  for (std::size_t i = 0; i < n; ++i) {
    z1[i] = points[i].x();
    z2[i] = points[i].y();
  }
  // The eigenvectors of any U = [1 u; u 1] (Maronna & Zamar's orthogonalisation in 2D).
  Eigen::Matrix2d e;
  e << 1.0, 1.0, 1.0, -1.0;
  e /= std::numbers::sqrt2;
  Eigen::Matrix2d a = Eigen::Matrix2d::Identity();
  for (int it = 0; it < o.iterations; ++it) {
    const auto s1 = Scale(z1, o.scale), s2 = Scale(z2, o.scale);
    if (!s1 || !s2 || !(s1->scale > 0.0) || !(s2->scale > 0.0)) return std::nullopt;
    // y = D^-1 z; z <- E^T y: the scaled sum and difference over sqrt 2.
    for (std::size_t i = 0; i < n; ++i) {
      const double y1 = z1[i] / s1->scale, y2 = z2[i] / s2->scale;
      z1[i] = (y1 + y2) / std::numbers::sqrt2;
      z2[i] = (y1 - y2) / std::numbers::sqrt2;
    }
    a = a * Eigen::Vector2d(s1->scale, s2->scale).asDiagonal() * e;
  }
  const auto f1 = Scale(z1, o.scale), f2 = Scale(z2, o.scale);
  if (!f1 || !f2 || !(f1->scale > 0.0) || !(f2->scale > 0.0)) return std::nullopt;
  OgkEstimate r;
  r.location = a * Eigen::Vector2d(f1->location, f2->location);
  r.scatter = a * Eigen::Vector2d(f1->scale * f1->scale, f2->scale * f2->scale).asDiagonal() * a.transpose();
  r.scatter = 0.5 * (r.scatter + r.scatter.transpose());
  r.retained = static_cast<int>(n);
  if (!o.reweight) return r;

  // Hard-rejection reweighting with Maronna & Zamar's adaptive cutoff.
  const Eigen::Matrix2d info = r.scatter.inverse();
  std::vector<double> d(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d v = points[i] - r.location;
    d[i] = v.dot(info * v);
  }
  std::vector<double> sorted = d;
  const double q = -2.0 * std::log1p(-o.reweight_quantile);  // chi2_2 quantile
  const double cutoff = q * Median(sorted) / (2.0 * std::numbers::ln2);
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  int m = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (d[i] <= cutoff) {
      mean += points[i];
      ++m;
    }
  }
  if (m < 3) return r;
  mean /= m;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    if (d[i] <= cutoff) cov += (points[i] - mean) * (points[i] - mean).transpose();
  }
  cov /= static_cast<double>(m);  // the ML form: N copies of a point set keep its covariance
  // E[x x^T | d <= q] = Sigma P(chi2_4 <= q) / P(chi2_2 <= q) at the normal.
  const double kept_moment = 1.0 - std::exp(-0.5 * q) * (1.0 + 0.5 * q);
  cov *= o.reweight_quantile / kept_moment;
  r.location = mean;
  r.scatter = 0.5 * (cov + cov.transpose());
  r.retained = m;
  return r;
}

}  // namespace mapmesh
