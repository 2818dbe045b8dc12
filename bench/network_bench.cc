// Joining submap chains (JoinSubmapNetwork, the joining back-end): the cost of one submap
// factor's normal equations from its Jacobian's structure against the dense products, and of a
// whole join of the shared problem (bench/joiner_problem.h: 50 submaps of 30 landmarks, here
// split into two robots' chains that share their landmarks) with the submaps' information
// matrices kept from the last join (as the agent does) against computed afresh; and a join
// started from the last one's frames and landmarks with its pairings judged on those frames
// (as the agent does since J1's sixth session) against the same start with the first pass; and
// 4 to 48 chains, one of them new: placed alone, or by the first pass over all of them.

#include <benchmark/benchmark.h>

#include <Eigen/LU>
#include <algorithm>

#include "bench/joiner_problem.h"
#include "common/merge/submap_network.h"
#include "common/slam/submap_joiner.h"
#include "common/slam/submap_slam.h"

namespace mapmesh {
namespace {

// Submap 10 of the shared problem linearised at its measurement.
struct OneFactor {
  Eigen::MatrixXd j, info;
  Eigen::VectorXd e;
  OneFactor() {
    const SubmapEstimate s = bench::MakeJoinerSubmaps()[10];
    std::vector<Eigen::Vector2d> points;
    for (std::size_t i = 0; i < s.keys.size(); ++i)
      points.push_back(s.x.segment<2>(3 + 2 * static_cast<Eigen::Index>(i)));
    e = PredictSubmap(Pose2{}, Pose2{s.x(0), s.x(1), s.x(2)}, points, &j) - s.x;
    e(2) += 0.01;
    info = s.p.inverse();
  }
};

void BM_SubmapNormalEquations(benchmark::State& state) {
  const OneFactor f;
  Eigen::MatrixXd h;
  Eigen::VectorXd g;
  for (auto _ : state) {
    SubmapNormalEquations(f.j, f.info, f.e, &h, &g);
    benchmark::DoNotOptimize(h.data());
  }
}
BENCHMARK(BM_SubmapNormalEquations)->Unit(benchmark::kMicrosecond);

// The baseline: J^T info J and J^T info e as dense products.
void BM_SubmapNormalEquationsDense(benchmark::State& state) {
  const OneFactor f;
  Eigen::MatrixXd h;
  Eigen::VectorXd g;
  for (auto _ : state) {
    const Eigen::MatrixXd m = f.info * f.j;
    h.noalias() = f.j.transpose() * m;
    g.noalias() = m.transpose() * f.e;
    benchmark::DoNotOptimize(h.data());
  }
}
BENCHMARK(BM_SubmapNormalEquationsDense)->Unit(benchmark::kMicrosecond);

// The shared problem as two robots' chains: submaps 0-24 robot 1's, 25-49 robot 2's (its frame
// where submap 25 starts, its start 0.2 m and 0.02 rad off), the landmarks paired by key.
struct TwoChains {
  std::vector<WireSubmap> one, two;
  std::map<LandmarkRef, int> groups;
  TwoChains() {
    const std::vector<SubmapEstimate> s = bench::MakeJoinerSubmaps();
    for (std::size_t k = 0; k < s.size(); ++k) {
      const bool first = k < s.size() / 2;
      const RobotId robot = first ? 1 : 2;
      const auto index = static_cast<std::uint32_t>(first ? k : k - s.size() / 2);
      (first ? one : two).push_back(*ToWire(s[k], {robot, 1, index}, 0.0, 1.0));
      for (std::uint32_t key : s[k].keys) groups[{robot, 1, key}] = static_cast<int>(key);
    }
  }
  std::vector<ChainInput> Chains() const {
    Pose2 start;
    for (const WireSubmap& w : one) start = start * Pose2{w.x(0), w.x(1), w.x(2)};
    ChainInput a{1, 1, {}, Pose2{}, {}, {}}, b{2, 1, {}, start * Pose2{0.2, -0.2, 0.02}, {}, {}};
    for (const WireSubmap& w : one) a.submaps.push_back(&w);
    for (const WireSubmap& w : two) b.submaps.push_back(&w);
    return {a, b};
  }
};

void JoinTwoChains(benchmark::State& state, bool keep_information) {
  const TwoChains p;
  const std::vector<ChainInput> chains = p.Chains();
  SubmapInformation kept;
  JoinSubmapNetwork(chains, p.groups, {}, &kept);
  NetworkResult r;
  for (auto _ : state) {
    r = keep_information ? JoinSubmapNetwork(chains, p.groups, {}, &kept) : JoinSubmapNetwork(chains, p.groups);
    benchmark::DoNotOptimize(r.landmarks.data());
  }
  state.counters["landmarks"] = static_cast<double>(r.landmarks.size());
  state.counters["iterations"] = r.iterations;
}

// A join from the last one's frames and landmarks (the same chains: the agent's change little
// from one period to the next), its pairings judged on the frames or by the first pass.
void JoinFromTheLastJoin(benchmark::State& state, bool judge_on_start_frames) {
  const TwoChains p;
  std::vector<ChainInput> chains = p.Chains();
  SubmapInformation kept;
  const NetworkResult last = JoinSubmapNetwork(chains, p.groups, {}, &kept);
  for (std::size_t c = 0; c < chains.size(); ++c) chains[c].start_frames = last.frames[c];
  for (const NetworkLandmark& l : last.landmarks) {
    for (const LandmarkRef& ref : l.refs) chains[ref.robot - 1].start_landmarks[ref.key] = l.mean;
  }
  NetworkOptions o;
  o.judge_on_start_frames = judge_on_start_frames;
  NetworkResult r;
  for (auto _ : state) {
    r = JoinSubmapNetwork(chains, p.groups, o, &kept);
    benchmark::DoNotOptimize(r.landmarks.data());
  }
  state.counters["landmarks"] = static_cast<double>(r.landmarks.size());
  state.counters["iterations"] = r.iterations;
  state.counters["first_pass"] = r.first_pass;
}

void BM_JoinSubmapNetworkOnTheLastFrames(benchmark::State& state) { JoinFromTheLastJoin(state, true); }
BENCHMARK(BM_JoinSubmapNetworkOnTheLastFrames)->Unit(benchmark::kMillisecond);

// The baseline: the same start, the first pass at every join.
void BM_JoinSubmapNetworkFirstPassEveryJoin(benchmark::State& state) { JoinFromTheLastJoin(state, false); }
BENCHMARK(BM_JoinSubmapNetworkFirstPassEveryJoin)->Unit(benchmark::kMillisecond);

// Many robots' chains that share the landmarks, as a joining agent holds them in a swarm (48
// chains of 199 submaps at 64 agents on park4): chain c is 4 consecutive submaps of the shared
// problem from submap 2c mod 46, its start 0.1 m and 0.01 rad off; the landmarks paired by key.
// Every chain starts from the last join's frames and landmarks but the last one, which enters
// anew (a chain just aligned): placed alone against the others' frames, then the pairings
// judged on the frames, against the baseline: the first pass over every chain, whose cost grew
// with the chains (a 64-agent park4 run took over 20 minutes).
void JoinManyChains(benchmark::State& state, bool place_alone) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const std::vector<SubmapEstimate> s = bench::MakeJoinerSubmaps();
  std::vector<std::vector<WireSubmap>> wire(n);
  std::map<LandmarkRef, int> groups;
  std::vector<ChainInput> chains;
  for (std::size_t c = 0; c < n; ++c) {
    const std::size_t first = (2 * c) % (s.size() - 4);
    const auto robot = static_cast<RobotId>(c + 1);
    Pose2 start;
    for (std::size_t k = 0; k < first; ++k) start = start * Pose2{s[k].x(0), s[k].x(1), s[k].x(2)};
    for (std::size_t k = 0; k < 4; ++k) {
      wire[c].push_back(*ToWire(s[first + k], {robot, 1, static_cast<std::uint32_t>(k)}, 0.0, 1.0));
      for (std::uint32_t key : s[first + k].keys) groups[{robot, 1, key}] = static_cast<int>(key);
    }
    ChainInput in{robot, 1, {}, c == 0 ? Pose2{} : start * Pose2{0.1, -0.1, 0.01}, {}, {}};
    for (const WireSubmap& w : wire[c]) in.submaps.push_back(&w);
    chains.push_back(in);
  }
  NetworkOptions o;
  o.place_new_chains_alone = place_alone;
  SubmapInformation kept;
  NetworkResult r;
  {  // every chain from the last join, but the last one
    const NetworkResult last = JoinSubmapNetwork(chains, groups, o, &kept);
    for (std::size_t c = 0; c < chains.size(); ++c) chains[c].start_frames = last.frames[c];
    for (const NetworkLandmark& l : last.landmarks) {
      for (const LandmarkRef& ref : l.refs) chains[ref.robot - 1].start_landmarks[ref.key] = l.mean;
    }
    chains.back().start_frames.clear();
    chains.back().start_landmarks.clear();
  }
  for (auto _ : state) {
    r = JoinSubmapNetwork(chains, groups, o, &kept);
    benchmark::DoNotOptimize(r.landmarks.data());
  }
  state.counters["landmarks"] = static_cast<double>(r.landmarks.size());
  state.counters["ties"] = r.ties;
  state.counters["ties_dropped"] = r.ties_dropped;
  state.counters["joined"] = static_cast<double>(std::count(r.joined.begin(), r.joined.end(), true));
  state.counters["placed_alone"] = r.placed_alone;
  state.counters["first_pass"] = r.first_pass;
}

void BM_JoinManyChainsOneNewPlacedAlone(benchmark::State& state) { JoinManyChains(state, true); }
BENCHMARK(BM_JoinManyChainsOneNewPlacedAlone)->Arg(4)->Arg(16)->Arg(48)->Unit(benchmark::kMillisecond);

// The baseline: the first pass over every chain.
void BM_JoinManyChainsOneNewFirstPass(benchmark::State& state) { JoinManyChains(state, false); }
BENCHMARK(BM_JoinManyChainsOneNewFirstPass)->Arg(4)->Arg(16)->Arg(48)->Unit(benchmark::kMillisecond);

void BM_JoinSubmapNetworkKeptInformation(benchmark::State& state) { JoinTwoChains(state, true); }
BENCHMARK(BM_JoinSubmapNetworkKeptInformation)->Unit(benchmark::kMillisecond);

// The baseline: every join computes every submap's information matrix afresh.
void BM_JoinSubmapNetwork(benchmark::State& state) { JoinTwoChains(state, false); }
BENCHMARK(BM_JoinSubmapNetwork)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mapmesh
