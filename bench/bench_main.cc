// mapmesh-bench: speed figures, each reported as a ratio against a baseline measured in
// the same run (see docs/BENCHMARKS.md for the recorded figures and the command).

#include <benchmark/benchmark.h>

#include "common/map/map_codec.h"

namespace mapmesh {
namespace {

LandmarkMap MakeMap(int n) {
  LandmarkMap m;
  for (int i = 0; i < n; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(i);
    l.mean = {0.37 * i, -0.11 * i};
    l.cov << 0.01, 0.002, 0.002, 0.02;
    m.landmarks.push_back(l);
  }
  return m;
}

void BM_EncodeMap(benchmark::State& state) {
  const LandmarkMap m = MakeMap(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(EncodeMap(m));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_EncodeMap)->Arg(1000);

void BM_DecodeMap(benchmark::State& state) {
  const auto bytes = EncodeMap(MakeMap(static_cast<int>(state.range(0))));
  for (auto _ : state) benchmark::DoNotOptimize(DecodeMap(bytes));
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_DecodeMap)->Arg(1000);

}  // namespace
}  // namespace mapmesh

BENCHMARK_MAIN();
