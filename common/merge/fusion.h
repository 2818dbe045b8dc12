#pragma once
// Fusing several estimates of one landmark (thesis 3.4, ALGORITHMS.md 5):
// - Maximum Likelihood (eq. 78-79): the sample mean and sample covariance of the means. It
//   ignores the inputs' covariances (a baseline; with two inputs its covariance is rank 1);
// - information fusion (eq. 83-84, the thesis's "modified M-estimator"): the sum of the
//   information matrices. Optimal for independent inputs, overconfident for correlated ones;
// - Covariance Intersection (eq. 90-93): a convex combination of the information matrices,
//   sum w = 1. Consistent whatever the inputs' correlation. Weights: equal (1/N; 0.5 for two,
//   the thesis default), or chosen to minimise the determinant or the trace of the fused
//   covariance. For 2x2 information matrices both optima are closed-form along any line in
//   the weights (det is quadratic, the trace of the inverse a ratio of a linear and a
//   quadratic function): two inputs need no search; more inputs use exact pairwise exchanges,
//   which converge to the optimum because log det is concave and trace(inverse) convex in w.
// - OGK (thesis 2.3.2, 3.4.4, after Sequeira, Tsourdos & Lazarus 2011): the robust location and
//   scatter (robust_covariance.h, Maronna & Zamar's reweighted OGK with the tau-scale) of a
//   point set standing for the inputs. Sequeira et al. apply OGK to the sensors' measurements;
//   a global map holds only each map's Gaussian, so each input N(m_n, P_n) is represented by a
//   fixed, deterministic quasi-sample: m_n + P_n^(1/2) q_k, the same 256 points q_k for every
//   input (OgkFusionPattern: 16 rings of 16 points, the rings at the radii whose squares are the
//   chi2_2 means over 16 equal-probability slices, each ring's angles offset by the golden
//   ratio; its mean is exactly 0 and its second moment exactly I). The union, the same number of
//   points from each input, stands for the equal mixture of the inputs, and OGK's location and
//   scatter are the fused mean and covariance, the scatter divided by OGK's scatter of the
//   pattern itself (0.945 I: the reweighting trims whole rings) so that N copies of one input
//   fuse to that input exactly, at any orientation. No 1/N: like Sequeira's, the covariance is
//   the robust spread of the data, not of their mean.
//   Consistency: were OGK's answer the mixture's moments, the fused estimate would be the mean
//   of the means with covariance (1/N) sum P_n + the spread of the means, and
//   Cov((1/N) sum e_n) <= (1/N) sum Cov(e_n) (Jensen, any correlation) would make it consistent
//   like CI. OGK departs from the moments (its location leans to denser inputs, the reweighting
//   trims tails), so this is no proof; fusion_test.cc checks it by Monte Carlo over correlated
//   inputs (mean NEES there 0.51, worst case 1.39, CI's 0.75: more conservative than CI). The
//   price: the fused covariance is about the inputs' average, never the shrinkage of CI or
//   information fusion. The gain: with three or more inputs, one that disagrees with the rest
//   is rejected by the reweighting instead of pulling the mean (CI moves its mean by the
//   outlier's weight and its covariance does not see the disagreement at all). With two
//   inputs OGK cannot tell which one is the outlier (half the points each).
// - CI-OGK (Sequeira et al.'s hybrid): CI with equal weights and OGK, whichever has the smaller
//   covariance-ellipse area pi sqrt(det) (ties: CI). With the construction above OGK's area is
//   almost never the smaller one (in none of fusion_test.cc's 300 random cases): CI's
//   covariance is at most the inputs' harmonic mean, OGK's about their arithmetic mean. It wins
//   when tight inputs agree and a much wider one is rejected, which CI's equal weights still
//   count. Note that the area rule also keeps CI when one input is an outlier: CI's covariance
//   does not see where the means are.
//
// Order: every method gives the same result whatever the order of the inputs (all are
// symmetric functions of the inputs; the CI optima are unique; OGK's medians and sums do not
// depend on the order of the points, up to rounding). Fusing one input at a time
// (sequential CI) is not the same as one N-way fusion and depends on the order: the store in
// global_map.h always fuses each landmark's inputs at once.

#include <Eigen/Core>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "common/types/choice.h"

namespace mapmesh {

enum class FusionMethod {
  kMaximumLikelihood,
  kInformation,
  kCiConstant,     // equal weights
  kCiDeterminant,  // weights minimising det of the fused covariance
  kCiTrace,        // weights minimising its trace
  kJoining,        // not a per-landmark rule: the agent joins the maps by least squares (map_joining.h);
                   // where one landmark's estimates are fused on their own, as kCiConstant
  kOgk,            // robust location and scatter of the inputs' quasi-samples
  kCiOgk,          // kCiConstant or kOgk, whichever has the smaller ellipse area
};
inline constexpr ChoiceTable<FusionMethod, 8> kFusionMethods{{{FusionMethod::kMaximumLikelihood, "ml"},
                                                              {FusionMethod::kInformation, "information"},
                                                              {FusionMethod::kCiConstant, "ci"},
                                                              {FusionMethod::kCiDeterminant, "ci_det"},
                                                              {FusionMethod::kCiTrace, "ci_trace"},
                                                              {FusionMethod::kJoining, "joining"},
                                                              {FusionMethod::kOgk, "ogk"},
                                                              {FusionMethod::kCiOgk, "ci_ogk"}}};
inline std::string_view ToString(FusionMethod m) { return NameOf(kFusionMethods, m); }
// "ml", "information", "ci", "ci_det", "ci_trace", "joining", "ogk", "ci_ogk"; nullopt for
// anything else.
inline std::optional<FusionMethod> ParseFusionMethod(std::string_view name) {
  return ParseChoice(kFusionMethods, name);
}

// A 2D Gaussian estimate.
struct Gaussian2 {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();
};

enum class FusionVerdict {
  kFused = 0,
  kNoInputs,
  kNonFiniteMean,
  kInvalidCovariance,   // not finite, not symmetric, or not positive semi-definite
  kSingularCovariance,  // positive semi-definite but not invertible: no information form
};

// Why an estimate cannot be fused, or kFused when it can.
FusionVerdict CheckEstimate(const Gaussian2& g);

struct FusionResult {
  FusionVerdict verdict = FusionVerdict::kNoInputs;
  bool ok() const { return verdict == FusionVerdict::kFused; }
  int bad_input = -1;  // the first input that was rejected
  Gaussian2 fused;
  std::vector<double> weights;  // CI (and CI-OGK when CI won): the weight of each input (sums to 1)
};

// Fuses the inputs with the method. Any invalid input rejects the whole fusion (nothing is
// fused from a bad estimate); a single valid input is returned as it is.
FusionResult Fuse(std::span<const Gaussian2> inputs, FusionMethod method);

enum class CiCriterion { kDeterminant, kTrace };

// Two inputs, without allocating (except kOgk and kCiOgk, which go through Fuse): the common
// case of the global map. nullopt when either input is invalid (CheckEstimate); *weight, when
// given, receives a's CI weight.
std::optional<Gaussian2> FusePair(const Gaussian2& a, const Gaussian2& b, FusionMethod method,
                                  double* weight = nullptr);

// CI of two valid inputs with a's weight w given.
Gaussian2 CiFuseWithWeight(const Gaussian2& a, const Gaussian2& b, double w);

// Two inputs with information matrices a and b: the weight w in [0, 1] of a in
// w a + (1 - w) b that minimises det (or trace) of its inverse, in closed form.
double CiWeight(const Eigen::Matrix2d& info_a, const Eigen::Matrix2d& info_b, CiCriterion criterion);

// The same weight by golden-section search on [0, 1], evaluating the fused covariance at each
// step (the thesis's numerical approach; a reference and benchmark baseline).
double CiWeightBySearch(const Eigen::Matrix2d& info_a, const Eigen::Matrix2d& info_b, CiCriterion criterion,
                        double tolerance = 1e-9);

// The 256 points that stand for N(0, I) in kOgk (mean exactly 0, second moment exactly I).
const std::vector<Eigen::Vector2d>& OgkFusionPattern();

}  // namespace mapmesh
