// Least-squares submap joining (SubmapJoiner): the cost of joining one more submap at 50
// submaps of 30 landmarks each, windowed (the agent's way: the last 8 submaps relinearised,
// the rest marginalised into a prior) against the baseline of a full re-solve of all 50.

#include <benchmark/benchmark.h>

#include "bench/joiner_problem.h"
#include "common/slam/submap_joiner.h"

namespace mapmesh {
namespace {

constexpr int kSubmaps = bench::kJoinerSubmaps;

// Joins submap 50 into a joiner holding the first 49, with the given window.
void JoinTheFiftieth(benchmark::State& state, int window) {
  const std::vector<SubmapEstimate> submaps = bench::MakeJoinerSubmaps();
  SubmapJoiner base({.window = window});
  for (int k = 0; k + 1 < kSubmaps; ++k) base.Add(submaps[k]);
  for (auto _ : state) {
    state.PauseTiming();
    SubmapJoiner j = base;
    state.ResumeTiming();
    j.Add(submaps.back());
    benchmark::DoNotOptimize(j.last().means.data());
  }
  state.counters["landmarks"] = static_cast<double>(base.landmarks());
  state.counters["frames"] = static_cast<double>(base.window_frames());
}

void BM_JoinSubmapWindowed(benchmark::State& state) { JoinTheFiftieth(state, 8); }
BENCHMARK(BM_JoinSubmapWindowed)->Unit(benchmark::kMillisecond);

void BM_JoinSubmapFullResolve(benchmark::State& state) { JoinTheFiftieth(state, 1000); }
BENCHMARK(BM_JoinSubmapFullResolve)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mapmesh
