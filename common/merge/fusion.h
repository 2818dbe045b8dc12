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
//
// Order: every method gives the same result whatever the order of the inputs (all are
// symmetric functions of the inputs; the CI optima are unique). Fusing one input at a time
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
};
inline constexpr ChoiceTable<FusionMethod, 6> kFusionMethods{{{FusionMethod::kMaximumLikelihood, "ml"},
                                                              {FusionMethod::kInformation, "information"},
                                                              {FusionMethod::kCiConstant, "ci"},
                                                              {FusionMethod::kCiDeterminant, "ci_det"},
                                                              {FusionMethod::kCiTrace, "ci_trace"},
                                                              {FusionMethod::kJoining, "joining"}}};
inline std::string_view ToString(FusionMethod m) { return NameOf(kFusionMethods, m); }
// "ml", "information", "ci", "ci_det", "ci_trace", "joining"; nullopt for anything else.
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
  std::vector<double> weights;  // CI: the weight of each input (sums to 1)
};

// Fuses the inputs with the method. Any invalid input rejects the whole fusion (nothing is
// fused from a bad estimate); a single valid input is returned as it is.
FusionResult Fuse(std::span<const Gaussian2> inputs, FusionMethod method);

enum class CiCriterion { kDeterminant, kTrace };

// Two inputs, without allocating: the common case of the global map. nullopt when either
// input is invalid (CheckEstimate); *weight, when given, receives a's CI weight.
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

}  // namespace mapmesh
