// The reference's cost (issue 34): the centralized batch optimum of park4 with 8 agents, solved
// by the project's sparse solver (common/solver/least_squares.h) from the robots' own optima,
// with every landmark's marginal covariance; beside it the whole reference as a run computes it
// (streams read, every single-robot solve, the central solve and the known-pose map), and the
// same central solve by Ceres where it is installed (batch_ceres_bench.cc).

#include <benchmark/benchmark.h>

#include "bench/batch_problem.h"
#include "lab/reference.h"

namespace mapmesh {
namespace {

// The fair optimum (no start known but the gauge's: the limit every gap is against, with the
// robots' sightings) and the known-starts one, as the reference solves them.
void BM_CentralBatch(benchmark::State& state, StartKnowledge starts) {
  const bench::BatchProblemData& d = bench::Park4x8();
  BatchSolution s;
  for (auto _ : state) {
    s = SolveCentralBatch(d.input.logs, d.singles, d.input.sightings, {{}, starts});
    benchmark::DoNotOptimize(s.map.landmarks.data());
  }
  state.counters["iterations"] = s.report.iterations;
  state.counters["variables"] = s.variables;
  state.counters["landmarks"] = static_cast<double>(s.map.size());
  state.counters["final_cost"] = s.report.final_cost;
}
BENCHMARK_CAPTURE(BM_CentralBatch, fair, StartKnowledge::kNone)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_CentralBatch, known_starts, StartKnowledge::kKnown)->Unit(benchmark::kMillisecond);

void BM_ReferencePark4x8(benchmark::State& state) {
  const Scenario sc = LoadScenario(MAPMESH_SOURCE_DIR "/scenarios/park4.yaml", {}, 8);
  for (auto _ : state) {
    const lab::Reference r = lab::ComputeReference(sc, {});
    benchmark::DoNotOptimize(r.central.rmse_aligned_m);
  }
}
BENCHMARK(BM_ReferencePark4x8)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mapmesh
