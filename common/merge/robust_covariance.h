#pragma once
// Robust location and scatter of 2D points: univariate robust scales (the MAD and the
// tau-scale) and the Orthogonalized Gnanadesikan-Kettenring estimator (OGK) built on them.
// Thesis 3.4.4 (Table 5, after Sequeira, Tsourdos & Lazarus 2011, IEEE TIM 60:3833) names the
// estimator, but the seed text lost the table's pseudo-code; only its description survives
// (scale the data D, line 3; initial covariance U, line 4; new base E from U's eigenvectors,
// line 5; project, robust variances, a parameter Omega, line 6; back-project, line 7). It is
// rebuilt here from the two papers it rests on:
// - Gnanadesikan & Kettenring (1972): with a robust scale s, cov(X, Y) =
//   (s(X + Y)^2 - s(X - Y)^2) / 4, exact for the standard deviation;
// - Maronna & Zamar (2002, Technometrics 44:307, "Robust estimates of location and dispersion
//   for high-dimensional datasets"): the orthogonalised GK. One step, on data z_i (first the
//   points x_i):
//     D = diag(s(z_1), s(z_2)) and y_i = D^-1 z_i                            (Table 5 line 3)
//     U = [1 u; u 1], u = (s(y_1 + y_2)^2 - s(y_1 - y_2)^2) / 4 (GK)          (line 4)
//     E = the eigenvectors of U, z_i <- E^T y_i, A <- A D E                   (line 5)
//   then, after the last step, the robust location m_j and scale s_j of each z_j
//     Gamma = diag(s_1^2, s_2^2)  (Table 5's Omega, we take it to be this)     (line 6)
//     location = A m, scatter = A Gamma A^T                                   (line 7).
//   Unlike GK's matrix, A Gamma A^T is always positive semi-definite. In 2D a correlation matrix
//   U = [1 u; u 1] has the eigenvectors (1, 1)/sqrt 2 and (1, -1)/sqrt 2 whatever u, so E is
//   that fixed 45-degree base (also a valid base of U = I, which keeps the estimate continuous
//   in the data) and the projections are the scaled sum and difference GK uses. Maronna &
//   Zamar iterate the step once more (two steps, their recommendation and the default here)
//   and then reweight: points with d_i = (x_i - m)^T S^-1 (x_i - m) <= d_0 =
//   chi2_2(beta) med(d) / chi2_2(0.5) keep weight 1, the others 0, and the location and
//   scatter become the retained points' mean and covariance. We divide that covariance by the
//   factor the truncation costs at the normal, P(chi2_4 <= q) / P(chi2_2 <= q) with
//   q = chi2_2(beta) (0.744 at beta = 0.9), so that the reweighted scatter, like the raw one,
//   estimates the covariance at the normal.
// The scale is Yohai & Zamar's tau-scale (Maronna & Zamar's choice, c1 = 4.5, c2 = 3) or the
// MAD, both normalised to the standard deviation at the normal.
//
// Equivariance (the maths, checked in tests/merge/robust_covariance_test.cc): the estimate moves
// with translations and with scalings, swaps and sign flips of the coordinates exactly (each
// step first divides by the coordinates' own robust scales). It is not rotation equivariant:
// rotating the data changes the 45-degree projections, so rotated data give a rotated scatter
// only up to the estimator's sampling error.

#include <Eigen/Core>
#include <optional>
#include <span>

namespace mapmesh {

// Median and 1.4826 * median |x - median| (the MAD, the standard deviation at the normal).
// nullopt for no values.
struct LocationScale {
  double location = 0.0;
  double scale = 0.0;
};
std::optional<LocationScale> MadLocationScale(std::span<const double> x);

// Yohai & Zamar's tau location and scale, as Maronna & Zamar (2002) use it: with the median
// med and the raw MAD s0, location = sum w_i x_i / sum w_i, w_i = W(x_i - med) / (c1 s0),
// W(u) = (1 - u^2)^2 for |u| <= 1, else 0; scale^2 = s0^2 mean(min(((x_i - location) / s0)^2,
// c2^2)) / E, with E = E[min(X^2, (c2 k)^2)] for X ~ N(0, 1) and k = Phi^-1(3/4), so that the
// scale is the standard deviation at the normal (robustbase's scaleTau2 normalisation).
// nullopt for no values or when more than half of them are equal (s0 = 0).
std::optional<LocationScale> TauLocationScale(std::span<const double> x, double c1 = 4.5, double c2 = 3.0);

enum class RobustScale { kTau, kMad };

// The OGK's choices (defaults: Maronna & Zamar's recommended estimator).
struct OgkOptions {
  RobustScale scale = RobustScale::kTau;  // the univariate scale and location
  int iterations = 2;                     // orthogonalisation steps, >= 1
  bool reweight = true;                   // the hard-rejection reweighting step
  double reweight_quantile = 0.9;         // beta of the reweighting cutoff, in (0, 1)
};

struct OgkEstimate {
  Eigen::Vector2d location = Eigen::Vector2d::Zero();
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();  // estimates the covariance at the normal
  int retained = 0;                                   // points the reweighting kept (all without it)
};

// The OGK location and scatter of points. nullopt for fewer than 3 points, non-finite points,
// or a robust scale of zero (more than half the points on one line along a projection).
std::optional<OgkEstimate> Ogk(std::span<const Eigen::Vector2d> points, const OgkOptions& options = {});

}  // namespace mapmesh
