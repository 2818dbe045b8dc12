// Least-squares submap joining (SubmapJoiner): the cost of joining one more submap at 50
// submaps of 30 landmarks each, windowed (the agent's way: the last 8 submaps relinearised,
// the rest marginalised into a prior) against the baseline of a full re-solve of all 50.

#include <benchmark/benchmark.h>

#include <Eigen/Cholesky>
#include <random>

#include "common/slam/submap_joiner.h"

namespace mapmesh {
namespace {

constexpr int kSubmaps = 50;
constexpr int kLandmarksPerSubmap = 30;

// A chain of kSubmaps frames 2 m apart around a 40 m circle, each submap mapping the 30
// nearest of 300 landmarks, measured with noise of a correlated covariance.
std::vector<SubmapEstimate> MakeSubmaps() {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-25.0, 25.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Eigen::Vector2d> world;
  for (int i = 0; i < 300; ++i) world.emplace_back(u(rng), u(rng));
  std::vector<Pose2> frames = {{}};
  for (int k = 0; k < kSubmaps; ++k) frames.push_back(frames.back() * Pose2{2.0, 0.0, 2.0 * M_PI / kSubmaps * 2.0});
  std::vector<SubmapEstimate> out;
  for (int k = 0; k < kSubmaps; ++k) {
    std::vector<std::pair<double, int>> by_distance;
    for (int i = 0; i < 300; ++i) {
      by_distance.push_back({(world[i] - Eigen::Vector2d(frames[k].x, frames[k].y)).norm(), i});
    }
    std::sort(by_distance.begin(), by_distance.end());
    SubmapEstimate s;
    std::vector<Eigen::Vector2d> seen;
    for (int j = 0; j < kLandmarksPerSubmap; ++j) {
      s.keys.push_back(static_cast<std::uint32_t>(by_distance[j].second));
      seen.push_back(world[by_distance[j].second]);
    }
    std::sort(s.keys.begin(), s.keys.end());
    seen.clear();
    for (std::uint32_t key : s.keys) seen.push_back(world[key]);
    const Eigen::VectorXd h = PredictSubmap(frames[k], frames[k + 1], seen);
    const Eigen::Index n = h.size();
    Eigen::MatrixXd a = 0.02 * Eigen::MatrixXd::Identity(n, n);
    a.col(2).array() += 0.01;  // a shared heading error
    s.p = a * a.transpose();
    Eigen::VectorXd e(n);
    for (Eigen::Index i = 0; i < n; ++i) e(i) = g(rng);
    s.x = h + a * e;
    out.push_back(s);
  }
  return out;
}

// Joins submap 50 into a joiner holding the first 49, with the given window.
void JoinTheFiftieth(benchmark::State& state, int window) {
  const std::vector<SubmapEstimate> submaps = MakeSubmaps();
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
