// mapmesh-bench: speed figures. Each is reported as a ratio against a baseline measured in
// the same run (see docs/BENCHMARKS.md for the recorded figures and the command).

#include <benchmark/benchmark.h>
#include <Eigen/LU>

#include <memory>
#include <type_traits>

#include "common/map/map_codec.h"
#include "common/merge/fusion.h"
#include "common/merge/global_map.h"
#include "common/merge/map_alignment.h"
#include "common/merge/map_joining.h"
#include "common/slam/cekf_slam.h"
#include "common/slam/ekf_slam.h"
#include "common/slam/observation_model.h"
#include "lab/synthetic_maps.h"
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

// A filter holding n landmarks on a 7.5 m grid centred on the robot, so that about 20 are
// within the compressed filter's active region (5 m region half-size, 12 m reach).
template <typename Filter>
std::unique_ptr<Filter> MakeFilledFilter(int n);

FilterNoise BenchNoise() {
  FilterNoise f;
  f.control_cov = Eigen::Vector2d(0.03 * 0.03, 0.0524 * 0.0524).asDiagonal();
  f.obs_cov = Eigen::Vector2d(0.05 * 0.05, std::pow(DegToRad(1.0), 2)).asDiagonal();
  return f;
}

void Fill(LandmarkFilter& f, int n) {
  const int side = static_cast<int>(std::ceil(std::sqrt(n)));
  int k = 0;
  for (int i = 0; i < side && k < n; ++i) {
    for (int j = 0; j < side && k < n; ++j, ++k) {
      const Eigen::Vector2d m((i - side / 2) * 7.5 + 1.3, (j - side / 2) * 7.5 + 0.7);
      f.Add(static_cast<LandmarkId>(k), ObserveRangeBearing(f.robot(), m));
    }
  }
}

template <>
std::unique_ptr<EkfSlam> MakeFilledFilter<EkfSlam>(int n) {
  auto f = std::make_unique<EkfSlam>(BenchNoise(), EkfOptions{/*first_estimates_jacobians=*/false});
  Fill(*f, n);
  return f;
}

template <>
std::unique_ptr<CekfSlam> MakeFilledFilter<CekfSlam>(int n) {
  auto f = std::make_unique<CekfSlam>(BenchNoise(), CekfOptions{5.0, 12.0},
                                      EkfOptions{/*first_estimates_jacobians=*/false});
  Fill(*f, n);
  f->Switch();  // settle, and make only the landmarks around the robot active
  return f;
}

// One scan's worth of work: 0.5 s of odometry (5 predictions) and a batch update with the
// landmarks within 8 m, as the agent does every scan. The robot circles in place, so the
// compressed filter never switches here (BM_CekfSwitch times that).
template <typename Filter>
void BM_ScanUpdate(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  auto f = MakeFilledFilter<Filter>(n);
  std::vector<std::pair<LandmarkId, Eigen::Vector2d>> obs;
  for (auto _ : state) {
    for (int k = 0; k < 5; ++k) f->Predict({0.3, 0.3, 0.0}, 0.1);
    obs.clear();
    for (LandmarkId id : f->Candidates()) {
      const Eigen::Vector2d z = ObserveRangeBearing(f->robot(), f->Mean(id));
      if (z(0) < 8.0) obs.push_back({id, z + Eigen::Vector2d(0.01, 0.002)});
    }
    f->Update(obs);
  }
  state.counters["landmarks"] = n;
  state.counters["observed"] = static_cast<double>(obs.size());
  if constexpr (std::is_same_v<Filter, CekfSlam>) state.counters["active"] = static_cast<double>(f->active_landmarks());
}
BENCHMARK_TEMPLATE(BM_ScanUpdate, EkfSlam)->Arg(250)->Arg(1000)->Arg(2000)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_ScanUpdate, CekfSlam)->Arg(250)->Arg(1000)->Arg(2000)->Unit(benchmark::kMicrosecond);

// A drive: 100 scans (50 s at 0.3 m/s, 15 m) straight through the grid, each with 5
// predictions and the landmarks within 8 m ahead; the compressed filter switches regions
// three times on the way. Time per iteration / 100 is the average time per scan, batch
// updates included.
template <typename Filter>
void BM_Drive100Scans(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  for (auto _ : state) {
    state.PauseTiming();
    auto f = MakeFilledFilter<Filter>(n);
    state.ResumeTiming();
    for (int scan = 0; scan < 100; ++scan) {
      for (int k = 0; k < 5; ++k) f->Predict({0.3, 0.0, 0.0}, 0.1);
      std::vector<std::pair<LandmarkId, Eigen::Vector2d>> obs;
      for (LandmarkId id : f->Candidates()) {
        const Eigen::Vector2d z = ObserveRangeBearing(f->robot(), f->Mean(id));
        if (z(0) < 8.0 && std::abs(z(1)) < M_PI / 2) obs.push_back({id, z + Eigen::Vector2d(0.01, 0.002)});
      }
      f->Update(obs);
    }
    if constexpr (std::is_same_v<Filter, CekfSlam>) state.counters["switches"] = f->switches();
  }
  state.counters["landmarks"] = n;
}
BENCHMARK_TEMPLATE(BM_Drive100Scans, EkfSlam)
    ->Arg(250)
    ->Arg(1000)
    ->Arg(2000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK_TEMPLATE(BM_Drive100Scans, CekfSlam)
    ->Arg(250)
    ->Arg(1000)
    ->Arg(2000)
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

// The compressed filter's batch update and re-partition when the robot leaves its region.
void BM_CekfSwitch(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  auto f = MakeFilledFilter<CekfSlam>(n);
  for (auto _ : state) f->Switch();
  state.counters["landmarks"] = n;
}
BENCHMARK(BM_CekfSwitch)->Arg(250)->Arg(1000)->Arg(2000)->Unit(benchmark::kMillisecond);

// Map alignment (M4): two maps of n landmarks at the thesis's density (0.08 per square
// metre) sharing a patch of `overlap`, sigma 0.1 m, random frames. Counters: share of
// correct alignments (within 0.2 m and 1 deg) over the pairs benchmarked.
lab::MapPair AlignmentCase(int n, double overlap, std::uint64_t seed) {
  lab::MapPairOptions o;
  o.landmarks = n;
  o.overlap = overlap;
  o.sigma_m = 0.1;
  o.density_per_m2 = 0.08;
  std::mt19937_64 rng(seed);
  return lab::MakeMapPair(o, rng);
}

bool Correct(const AlignmentResult& r, const lab::MapPair& p) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const Landmark& l : p.b.landmarks) c += l.mean;
  c /= static_cast<double>(p.b.size());
  return r.accepted() && (r.transform.Apply(c) - p.truth.Apply(c)).norm() <= 0.2 &&
         std::abs(WrapAngle(r.transform.theta - p.truth.theta)) <= DegToRad(1.0);
}

// The whole pipeline: triangles, matching, RANSAC, refinement, tests.
void BM_AlignMaps(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const double overlap = static_cast<double>(state.range(1)) / 100.0;
  std::vector<lab::MapPair> cases;
  for (int k = 0; k < 20; ++k) cases.push_back(AlignmentCase(n, overlap, 1000 + k));
  std::mt19937_64 rng(1);
  std::size_t k = 0;
  int correct = 0, runs = 0;
  for (auto _ : state) {
    const lab::MapPair& p = cases[k++ % cases.size()];
    const AlignmentResult r = AlignMaps(p.a, p.b, {}, rng);
    correct += Correct(r, p);
    ++runs;
  }
  state.counters["success"] = static_cast<double>(correct) / runs;
}
BENCHMARK(BM_AlignMaps)
    ->Args({1000, 10})
    ->Args({60, 50})
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

// The baseline: RANSAC over every landmark pair (no triangle pre-filter), same tests.
void BM_AllPairsRansac(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const double overlap = static_cast<double>(state.range(1)) / 100.0;
  std::vector<lab::MapPair> cases;
  for (int k = 0; k < 5; ++k) cases.push_back(AlignmentCase(n, overlap, 1000 + k));
  AlignmentOptions o;
  o.max_iterations = 2000000;
  std::mt19937_64 rng(1);
  std::size_t k = 0;
  int correct = 0, runs = 0;
  for (auto _ : state) {
    const lab::MapPair& p = cases[k++ % cases.size()];
    std::vector<CandidatePair> all;
    for (int i = 0; i < static_cast<int>(p.a.size()); ++i) {
      for (int j = 0; j < static_cast<int>(p.b.size()); ++j) all.push_back({i, j, 1});
    }
    const AlignmentResult r = RansacAlign(p.a, p.b, all, o, rng);
    correct += Correct(r, p);
    ++runs;
  }
  state.counters["success"] = static_cast<double>(correct) / runs;
}
BENCHMARK(BM_AllPairsRansac)->Args({60, 50})->Unit(benchmark::kMillisecond)->Iterations(5);

// Fusion (M5): CI of 1000 landmark pairs with the determinant-minimising weight, in closed
// form against the thesis's approach, a numerical search (golden section to 1e-6, forming
// the fused covariance at every step). Random covariances, eigenvalues 0.01-1 m^2.
std::vector<std::pair<Gaussian2, Gaussian2>> FusionPairs(int n) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.01, 1.0), ang(0.0, 3.14159), pos(-50.0, 50.0);
  auto estimate = [&] {
    const double a = ang(rng);
    Eigen::Matrix2d r;
    r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
    const Eigen::Matrix2d cov = r * Eigen::Vector2d(u(rng), u(rng)).asDiagonal() * r.transpose();
    return Gaussian2{{pos(rng), pos(rng)}, 0.5 * (cov + cov.transpose())};
  };
  std::vector<std::pair<Gaussian2, Gaussian2>> out;
  for (int i = 0; i < n; ++i) out.emplace_back(estimate(), estimate());
  return out;
}

void BM_CiClosedForm(benchmark::State& state) {
  const auto pairs = FusionPairs(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    for (const auto& [a, b] : pairs) benchmark::DoNotOptimize(FusePair(a, b, FusionMethod::kCiDeterminant));
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_CiClosedForm)->Arg(1000)->Unit(benchmark::kMicrosecond);

void BM_CiGoldenSection(benchmark::State& state) {
  const auto pairs = FusionPairs(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    for (const auto& [a, b] : pairs) {
      const double w = CiWeightBySearch(a.cov.inverse(), b.cov.inverse(), CiCriterion::kDeterminant, 1e-6);
      benchmark::DoNotOptimize(CiFuseWithWeight(a, b, w));
    }
  }
  state.SetItemsProcessed(state.iterations() * state.range(0));
}
BENCHMARK(BM_CiGoldenSection)->Arg(1000)->Unit(benchmark::kMicrosecond);

// A full global-map rebuild: a 500-landmark local map and 4 peers' 500-landmark maps of the
// same area (each with its own noise and frame), every peer aligned with a small transform
// covariance; CI with the determinant-minimising weight (the baseline), or that build followed
// by the least-squares joining of the same maps (`fusion: joining`, which needs the CI build's
// association).
void GlobalMapRebuild(benchmark::State& state, bool joining) {
  const int n = static_cast<int>(state.range(1)), peers = static_cast<int>(state.range(0));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 80.0), ua(-3.1, 3.1), ut(-50.0, 50.0);
  std::normal_distribution<double> g(0.0, 0.1);
  std::vector<Eigen::Vector2d> world;
  while (static_cast<int>(world.size()) < n) {
    const Eigen::Vector2d p(u(rng), u(rng));
    bool far = true;
    for (const auto& q : world) far = far && (p - q).norm() > 1.5;
    if (far) world.push_back(p);
  }
  auto map_in = [&](const Pose2& frame) {
    LandmarkMap m;
    const Pose2 inv = frame.Inverse();
    for (std::size_t i = 0; i < world.size(); ++i) {
      m.landmarks.push_back({static_cast<std::uint32_t>(i), -1, inv.Apply(world[i] + Eigen::Vector2d(g(rng), g(rng))),
                             0.01 * Eigen::Matrix2d::Identity()});
    }
    return m;
  };
  const LandmarkMap local = map_in({});
  std::vector<MapSource> sources;
  Eigen::Matrix3d tc = Eigen::Matrix3d::Zero();
  tc.diagonal() << 1e-4, 1e-4, 1e-7;
  for (int k = 0; k < peers; ++k) {
    const Pose2 frame{ut(rng), ut(rng), ua(rng)};
    sources.push_back({static_cast<RobotId>(k + 2), 0, map_in(frame), frame, tc});
  }
  GlobalMapOptions o;
  o.method = FusionMethod::kCiDeterminant;
  std::size_t size = 0;
  for (auto _ : state) {
    GlobalMap gm = BuildGlobalMap(local, 1, sources, o);
    if (joining) gm = JoinMaps(local, 1, 0, sources, gm);
    size = gm.map.size();
    benchmark::DoNotOptimize(size);
  }
  state.counters["landmarks"] = static_cast<double>(size);
}
void BM_GlobalMapRebuild(benchmark::State& state) { GlobalMapRebuild(state, false); }
void BM_GlobalMapRebuildJoining(benchmark::State& state) { GlobalMapRebuild(state, true); }
BENCHMARK(BM_GlobalMapRebuild)->Args({4, 15})->Args({4, 500})->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GlobalMapRebuildJoining)->Args({4, 15})->Args({4, 500})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mapmesh

BENCHMARK_MAIN();
