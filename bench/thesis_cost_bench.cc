// The thesis's cost figures (chapter 5.1, issue T1 item 5; docs/BENCHMARKS.md "The thesis's cost
// figures (T1)", scripts/plots/cost.py):
// - Fig. 43: Delaunay triangulation of n random landmarks (BM_ThesisDelaunay/n);
// - Fig. 47: RANSAC's two steps against the number of candidate pairs: one hypothesis from a
//   two-pair sample (BM_ThesisRansacHypothesis/m) and one consensus test of a hypothesis over
//   every candidate (BM_ThesisRansacConsensus/<distance>/m);
// - Fig. 54: fusing each of n landmarks' two estimates by Maximum Likelihood, information
//   fusion (the thesis's modified M-estimator) and CI with the constant weight
//   (BM_ThesisFuse/<method>/n);
// - Table 6: CI with the constant weight against the determinant-optimal weight, in closed
//   form (the project's) and by golden-section search (the thesis's numerical approach).
// Every input is seeded; every name starts with BM_Thesis, so --benchmark_filter=Thesis runs
// them all and nothing else.

#include <benchmark/benchmark.h>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "common/geometry/rigid_fit.h"
#include "common/geometry/spatial.h"
#include "common/merge/alignment_fit.h"
#include "common/merge/fusion.h"
#include "common/merge/map_alignment.h"

namespace mapmesh {
namespace {

// The thesis's random map: n landmarks uniform over a square at its density (0.08 per m^2).
std::vector<Eigen::Vector2d> RandomLandmarks(int n, std::mt19937_64& rng) {
  const double side = std::sqrt(n / 0.08);
  std::uniform_real_distribution<double> u(0.0, side);
  std::vector<Eigen::Vector2d> p(static_cast<std::size_t>(n));
  for (auto& x : p) x = {u(rng), u(rng)};
  return p;
}

// Fig. 43: CGAL's Delaunay triangulation (common/geometry/spatial.h, what triangle matching
// calls), over 10 landmark sets per size, cycled.
void BM_ThesisDelaunay(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::mt19937_64 rng(43);
  std::vector<std::vector<Eigen::Vector2d>> sets;
  for (int k = 0; k < 10; ++k) sets.push_back(RandomLandmarks(n, rng));
  std::size_t k = 0, triangles = 0;
  for (auto _ : state) {
    const auto t = DelaunayTriangles(sets[k++ % sets.size()]);
    triangles = t.size();
    benchmark::DoNotOptimize(t.data());
  }
  state.counters["landmarks"] = n;
  state.counters["triangles"] = static_cast<double>(triangles);
}
BENCHMARK(BM_ThesisDelaunay)->Arg(50)->Arg(100)->Arg(200)->Arg(400)->Arg(500)->Arg(1000)->Unit(benchmark::kMicrosecond);

// Fig. 47's input: m candidate pairs between map A (m random landmarks, sigma 0.1 m) and map B
// (the same landmarks with their own noise, seen in another frame); half the candidates pair a
// landmark with itself (inliers), half with a random other one (outliers), shuffled.
struct RansacCase {
  LandmarkMap a, b;
  std::vector<CandidatePair> candidates;
};

RansacCase MakeRansacCase(int m, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const std::vector<Eigen::Vector2d> world = RandomLandmarks(m, rng);
  std::normal_distribution<double> noise(0.0, 0.1);
  const Pose2 frame{12.0, -7.0, 0.8};  // B's frame in A's
  const Pose2 inv = frame.Inverse();
  const Eigen::Matrix2d cov = 0.01 * Eigen::Matrix2d::Identity();
  RansacCase c;
  for (int i = 0; i < m; ++i) {
    const auto id = static_cast<std::uint32_t>(i);
    c.a.landmarks.push_back({id, -1, world[i] + Eigen::Vector2d(noise(rng), noise(rng)), cov});
    c.b.landmarks.push_back({id, -1, inv.Apply(world[i] + Eigen::Vector2d(noise(rng), noise(rng))), cov});
  }
  std::uniform_int_distribution<int> any(0, m - 1);
  for (int i = 0; i < m; ++i) {
    int j = i;
    if (i % 2 == 1) {
      while (j == i) j = any(rng);
    }
    c.candidates.push_back({i, j, 1});
  }
  std::shuffle(c.candidates.begin(), c.candidates.end(), rng);
  return c;
}

// Fig. 47's candidate counts (the thesis's "sample number").
void CandidateCounts(benchmark::internal::Benchmark* b) {
  for (int m : {10, 20, 50, 100, 200, 500, 1000}) b->Arg(m);
}

// One hypothesis as RansacAlign draws it: a random two-pair sample (the thesis's minimum sample
// set) and the closed-form two-point transform (eq. 57-59). Samples sharing a landmark are
// drawn again, as RansacAlign skips them.
void BM_ThesisRansacHypothesis(benchmark::State& state) {
  const int m = static_cast<int>(state.range(0));
  const RansacCase c = MakeRansacCase(m, 47);
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<std::size_t> pick(0, c.candidates.size() - 1);
  for (auto _ : state) {
    const CandidatePair *c1 = nullptr, *c2 = nullptr;
    do {
      c1 = &c.candidates[pick(rng)];
      c2 = &c.candidates[pick(rng)];
    } while (c1->a == c2->a || c1->b == c2->b);
    benchmark::DoNotOptimize(FitRigid2D(c.b.landmarks[c1->b].mean, c.b.landmarks[c2->b].mean, c.a.landmarks[c1->a].mean,
                                        c.a.landmarks[c2->a].mean));
  }
  state.counters["candidates"] = m;
}
BENCHMARK(BM_ThesisRansacHypothesis)->Apply(CandidateCounts)->Unit(benchmark::kNanosecond);

// One consensus test, RansacAlign's own (alignment_detail::ConsensusScorer): every candidate's
// gated distance under the hypothesis (Mahalanobis at the 99 % chi-square gate or Euclidean
// within 2 m), and the support counted once per landmark on each side. Hypotheses from 64
// random samples, cycled (most are wrong, as in RANSAC).
void ThesisRansacConsensus(benchmark::State& state, ConsensusDistance distance) {
  const int m = static_cast<int>(state.range(0));
  const RansacCase c = MakeRansacCase(m, 47);
  AlignmentOptions o;
  o.distance = distance;
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<std::size_t> pick(0, c.candidates.size() - 1);
  std::vector<PoseMap2> hypotheses;
  while (hypotheses.size() < 64) {
    const CandidatePair &c1 = c.candidates[pick(rng)], &c2 = c.candidates[pick(rng)];
    if (c1.a == c2.a || c1.b == c2.b) continue;
    const auto t = FitRigid2D(c.b.landmarks[c1.b].mean, c.b.landmarks[c2.b].mean, c.a.landmarks[c1.a].mean,
                              c.a.landmarks[c2.a].mean);
    if (t) hypotheses.emplace_back(*t);
  }
  alignment_detail::ConsensusScorer scorer(c.a, c.b, c.candidates, o);
  std::vector<char> in;
  std::size_t k = 0;
  double support_sum = 0.0;
  for (auto _ : state) {
    const alignment_detail::ConsensusScorer::Score s = scorer.Evaluate(hypotheses[k++ % hypotheses.size()], in);
    benchmark::DoNotOptimize(s.cost);
    support_sum += s.support;
  }
  state.counters["candidates"] = m;
  state.counters["mean_support"] = support_sum / static_cast<double>(state.iterations());
}
BENCHMARK_CAPTURE(ThesisRansacConsensus, mahalanobis, ConsensusDistance::kMahalanobis)
    ->Name("BM_ThesisRansacConsensus/mahalanobis")
    ->Apply(CandidateCounts)
    ->Unit(benchmark::kNanosecond);
BENCHMARK_CAPTURE(ThesisRansacConsensus, euclidean, ConsensusDistance::kEuclidean)
    ->Name("BM_ThesisRansacConsensus/euclidean")
    ->Apply(CandidateCounts)
    ->Unit(benchmark::kNanosecond);

// Fig. 54 and Table 6's input, as the thesis made it: n landmarks, each with two estimates of
// zero-mean Gaussian position (sigma 10 m) and a random covariance (eigenvalues 0.01-1 m^2,
// random orientation).
std::vector<std::pair<Gaussian2, Gaussian2>> LandmarkEstimates(int n) {
  std::mt19937_64 rng(54);
  std::normal_distribution<double> pos(0.0, 10.0);
  std::uniform_real_distribution<double> eig(0.01, 1.0), ang(0.0, M_PI);
  auto estimate = [&] {
    const double a = ang(rng);
    Eigen::Matrix2d r;
    r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
    const Eigen::Matrix2d cov = r * Eigen::Vector2d(eig(rng), eig(rng)).asDiagonal() * r.transpose();
    return Gaussian2{{pos(rng), pos(rng)}, 0.5 * (cov + cov.transpose())};
  };
  std::vector<std::pair<Gaussian2, Gaussian2>> out;
  for (int i = 0; i < n; ++i) out.emplace_back(estimate(), estimate());
  return out;
}

// Each of the n landmarks' two estimates fused by FusePair (what the global map calls, input
// checks included).
void ThesisFuse(benchmark::State& state, FusionMethod method) {
  const int n = static_cast<int>(state.range(0));
  const auto pairs = LandmarkEstimates(n);
  for (auto _ : state) {
    for (const auto& [a, b] : pairs) benchmark::DoNotOptimize(FusePair(a, b, method));
  }
  state.counters["landmarks"] = n;
  state.SetItemsProcessed(state.iterations() * state.range(0));
}

// The determinant-optimal weight found as the thesis did, by a numerical search: golden
// section to 1e-6 on [0, 1], forming the fused covariance at every step (CiWeightBySearch),
// after the same input checks as FusePair.
void ThesisFuseCiDetSearch(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const auto pairs = LandmarkEstimates(n);
  for (auto _ : state) {
    for (const auto& [a, b] : pairs) {
      if (CheckEstimate(a) != FusionVerdict::kFused || CheckEstimate(b) != FusionVerdict::kFused) continue;
      const double w = CiWeightBySearch(a.cov.inverse(), b.cov.inverse(), CiCriterion::kDeterminant, 1e-6);
      benchmark::DoNotOptimize(CiFuseWithWeight(a, b, w));
    }
  }
  state.counters["landmarks"] = n;
  state.SetItemsProcessed(state.iterations() * state.range(0));
}

// Fig. 54's and Table 6's landmark counts.
void LandmarkCounts(benchmark::internal::Benchmark* b) {
  for (int n : {2, 10, 100, 1000}) b->Arg(n);
  b->Unit(benchmark::kMicrosecond);
}
BENCHMARK_CAPTURE(ThesisFuse, ml, FusionMethod::kMaximumLikelihood)->Name("BM_ThesisFuse/ml")->Apply(LandmarkCounts);
BENCHMARK_CAPTURE(ThesisFuse, information, FusionMethod::kInformation)
    ->Name("BM_ThesisFuse/information")
    ->Apply(LandmarkCounts);
BENCHMARK_CAPTURE(ThesisFuse, ci, FusionMethod::kCiConstant)->Name("BM_ThesisFuse/ci")->Apply(LandmarkCounts);
BENCHMARK_CAPTURE(ThesisFuse, ci_det, FusionMethod::kCiDeterminant)
    ->Name("BM_ThesisFuse/ci_det")
    ->Apply(LandmarkCounts);
BENCHMARK(ThesisFuseCiDetSearch)->Name("BM_ThesisFuse/ci_det_search")->Apply(LandmarkCounts);

}  // namespace
}  // namespace mapmesh
