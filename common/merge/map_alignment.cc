#include "common/merge/map_alignment.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "common/geometry/rigid_fit.h"
#include "common/merge/alignment_fit.h"
#include "common/merge/global_map.h"
#include "common/merge/transform_search.h"
#include "common/solver/chi2.h"

namespace mapmesh {
namespace {

using alignment_detail::Conclude;
using alignment_detail::ForAlignment;
using alignment_detail::GatedD2;
using alignment_detail::LargestSigma;
using alignment_detail::OneToOne;
using alignment_detail::Usable;
using alignment_detail::UsableLandmarks;

struct Hypothesis {
  Pose2 t;
  int support = -1;
  double cost = std::numeric_limits<double>::infinity();
  bool BetterThan(const Hypothesis& o) const { return support > o.support || (support == o.support && cost < o.cost); }
};

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
  auto inlier_d2 = [&](const CandidatePair& c, const PoseMap2& t) {
    return GatedD2(a.landmarks[c.a], b.landmarks[c.b], t, o, gate);
  };
  // Each hypothesis marks its inlier candidates, and counts those it shares with the best and
  // the runner-up so far: two hypotheses that share most of their inliers are one alignment,
  // however far apart their parameters (a long map turns a small rotation difference into
  // metres); two that share few are different alignments, however close.
  struct Marked : Hypothesis {
    std::vector<char> in;
    int pairs = 0;
  };
  alignment_detail::ConsensusScorer scorer(a, b, cand, o);
  std::vector<char> scratch(cand.size(), 0);
  Marked best, runner;
  best.in.assign(cand.size(), 0);
  runner.in.assign(cand.size(), 0);
  int shared_best = 0, shared_runner = 0;
  auto evaluate = [&](const Pose2& t) {
    const alignment_detail::ConsensusScorer::Score s = scorer.Evaluate(PoseMap2(t), scratch);
    shared_best = shared_runner = 0;
    for (std::size_t i = 0; i < cand.size(); ++i) {
      if (!scratch[i]) continue;
      shared_best += best.in[i];
      shared_runner += runner.in[i];
    }
    return std::pair<Hypothesis, int>(Hypothesis{t, s.support, s.cost}, s.pairs);
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
    const double tol = rigid_tol > 0
                           ? rigid_tol
                           : 3.0 * std::sqrt(std::pow(LargestSigma(a1.cov), 2) + std::pow(LargestSigma(a2.cov), 2) +
                                             std::pow(LargestSigma(b1.cov), 2) + std::pow(LargestSigma(b2.cov), 2));
    if (dist_gap > tol) continue;
    const std::optional<Pose2> t = FitRigid2D(b1.mean, b2.mean, a1.mean, a2.mean);
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
        bound = std::max<long>(50,
                               static_cast<long>(std::ceil(std::log(1.0 - o.success_probability) / std::log(1.0 - q))));
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
  const PoseMap2 best_t(best.t);
  for (const CandidatePair& c : cand) {
    const double d2 = inlier_d2(c, best_t);
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

AlignmentResult VerifyUncertainAlignment(const LandmarkMap& a, const LandmarkMap& b, const Pose2& guess,
                                         const Eigen::Matrix3d& guess_cov, const AlignmentOptions& o) {
  LandmarkMap moved = b;
  const PoseMap2 tm(guess);
  for (Landmark& l : moved.landmarks) l = TransformLandmark(l, tm, guess_cov, nullptr);
  moved.shape_sigma_m = 0.0;  // the guess's error is not a shape error: compare with the marginals
  const AlignmentResult near = VerifyAlignment(a, moved, Pose2{}, o);
  return VerifyAlignment(a, b, near.accepted() ? near.transform * guess : guess, o);
}

AlignmentResult AlignMaps(const LandmarkMap& a, const LandmarkMap& b, const AlignmentOptions& o, std::mt19937_64& rng) {
  if (o.search == TransformSearch::kIterativeTranslation) return TranslationSearchAlign(a, b, o);
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
  AlignmentResult r = o.search == TransformSearch::kAdaptiveRandomWalk ? RandomWalkAlign(a, b, cand, o, rng)
                                                                       : RansacAlign(a, b, cand, o, rng);
  r.best_patch = stats.best_patch;
  r.patches = stats.patches;
  r.usable_a = stats.usable_a;
  r.usable_b = stats.usable_b;
  r.triangles_a = stats.triangles_a;
  r.triangles_b = stats.triangles_b;
  return r;
}

}  // namespace mapmesh
