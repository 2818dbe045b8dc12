// mapmesh-bench: speed figures. Each is reported as a ratio against a baseline measured in
// the same run (see docs/BENCHMARKS.md for the recorded figures and the command).

#include <benchmark/benchmark.h>

#include "common/map/map_codec.h"
#include "sim_feeder/simulator.h"

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

// Stream generation: robots x landmarks world, 60 simulated seconds per iteration. The
// counter x_realtime is simulated seconds per wall second (the baseline is real time).
void BM_SimulatorStream(benchmark::State& state) {
  const int robots = static_cast<int>(state.range(0)), landmarks = static_cast<int>(state.range(1));
  const Scenario sc = ParseScenario(
      "duration_s: 60\nworld: {landmarks: {generator: {count: " + std::to_string(landmarks) +
          ", area_m: [0, 0, 100, 100], min_spacing_m: 1.5}}}\nrobots: {count: " + std::to_string(robots) +
          ", defaults: {preset: thesis, path: {type: random, count: 10}, sensor: {signatures: true}}}\nradio: {range_m: 30}\n",
      "bench.yaml");
  const World world = BuildWorld(sc);
  std::size_t observations = 0;
  for (auto _ : state) {
    Simulator sim(sc, world);
    while (!sim.Done()) {
      const FeedBatch b = sim.Next();
      for (const Scan& s : b.scans) observations += s.obs.size();
      benchmark::DoNotOptimize(b);
    }
  }
  state.counters["x_realtime"] = benchmark::Counter(60.0 * static_cast<double>(state.iterations()),
                                                    benchmark::Counter::kIsRate);
  state.counters["observations"] = benchmark::Counter(static_cast<double>(observations), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_SimulatorStream)->Args({32, 1000})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace mapmesh

BENCHMARK_MAIN();
