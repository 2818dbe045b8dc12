// The dense path of BlockNormalEquations (Factorisation::kAuto takes it when the factor would
// hold at least kDenseFillShare of the triangle) against the sparse simplicial factorisation it
// replaces there, on the normal equations of a summarised join: 212 landmarks (2 each) and 11
// frames (3 each) under four dense factors, one per chain, each over a random two thirds of the
// landmarks and a few frames (a summary couples all of its chain's landmarks). One iteration:
// a factorisation, a solve and every landmark's marginal covariance, as a join ends.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>

#include "common/solver/least_squares.h"

namespace mapmesh {
namespace {

struct DenseJoin {
  std::vector<int> sizes;
  std::vector<std::vector<int>> vars;  // per factor
  std::vector<Eigen::MatrixXd> h;      // per factor: its information
  std::vector<Eigen::VectorXd> g;
  std::vector<int> landmarks;
  DenseJoin() {
    std::mt19937_64 rng(17);
    constexpr int kFrames = 11, kLandmarks = 212;
    for (int f = 0; f < kFrames; ++f) sizes.push_back(3);
    for (int l = 0; l < kLandmarks; ++l) {
      landmarks.push_back(static_cast<int>(sizes.size()));
      sizes.push_back(2);
    }
    for (int chain = 0; chain < 4; ++chain) {
      std::vector<int> v = {chain % kFrames, (chain + 4) % kFrames, (chain + 8) % kFrames};
      for (int l : landmarks) {
        if (rng() % 3 != 0) v.push_back(l);
      }
      int n = 0;
      for (int x : v) n += sizes[static_cast<std::size_t>(x)];
      std::normal_distribution<double> normal;
      Eigen::MatrixXd a(n, n);
      for (int i = 0; i < a.size(); ++i) a.data()[i] = normal(rng);
      h.push_back(a * a.transpose() / n + Eigen::MatrixXd::Identity(n, n));
      Eigen::VectorXd r(n);
      for (int i = 0; i < n; ++i) r(i) = normal(rng);
      g.push_back(r);
      vars.push_back(std::move(v));
    }
  }
};

void Run(benchmark::State& state, Factorisation factorisation) {
  const DenseJoin p;
  BlockNormalEquations eq(p.sizes, factorisation);
  std::vector<int> handles;
  for (const auto& v : p.vars) handles.push_back(eq.Couple(v));
  eq.Finalize();
  Eigen::VectorXd dx;
  for (auto _ : state) {
    eq.SetZero();
    for (std::size_t f = 0; f < handles.size(); ++f) eq.AddInformation(handles[f], p.h[f], p.g[f]);
    if (!eq.Solve(0.0, &dx)) state.SkipWithError("not positive definite");
    const std::vector<Eigen::MatrixXd> m = eq.Marginals(p.landmarks);
    benchmark::DoNotOptimize(m.data());
  }
  state.counters["dense"] = eq.dense() ? 1 : 0;
  state.counters["fill"] = static_cast<double>(eq.factor_entries()) / (0.5 * eq.dim() * (eq.dim() + 1));
}

// The baseline: the sparse simplicial factorisation forced.
void BM_DenseJoinSparse(benchmark::State& state) { Run(state, Factorisation::kSparse); }
BENCHMARK(BM_DenseJoinSparse)->Unit(benchmark::kMillisecond);

// What kAuto takes on it: the dense path.
void BM_DenseJoinAuto(benchmark::State& state) { Run(state, Factorisation::kAuto); }
BENCHMARK(BM_DenseJoinAuto)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mapmesh
