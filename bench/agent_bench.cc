// Agent input costs: what one peer map costs the receiving agent (AgentNode::OnMap), for a
// map it takes (the baseline) and for a 100 000-landmark map it refuses before decoding
// (agent.max_peer_landmarks), with the decoding it is spared beside them.

#include <benchmark/benchmark.h>

#include <random>

#include "agent/agent_node.h"
#include "agent/agent_setup.h"
#include "common/config/scenario.h"
#include "common/map/map_codec.h"

namespace mapmesh {
namespace {

class NullOutput : public AgentOutput {
 public:
  void PublishMap(const MapMessage&) override {}
  void PublishStatus(const AgentStatus&) override {}
};

std::vector<std::uint8_t> RandomPayload(int n) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 200.0);
  LandmarkMap m;
  for (int i = 0; i < n; ++i)
    m.landmarks.push_back({static_cast<std::uint32_t>(i), -1, {u(rng), u(rng)}, 0.01 * Eigen::Matrix2d::Identity()});
  return EncodeMap(m);
}

// range(0): landmarks in the peer's map. Each iteration is one new version of it.
void BM_AgentReceivesPeerMap(benchmark::State& state) {
  const Scenario sc = ParseScenario(R"(version: 1
world: {landmarks: {list: [[5, 0], [0, 5]]}}
robots: {list: [{id: 1, start: [0, 0, 0]}, {id: 2, start: [1, 0, 0]}]}
)",
                                    "bench.yaml");
  NullOutput out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}}});
  MapMessage msg;
  msg.robot_id = 2;
  msg.incarnation = 1;
  msg.payload = RandomPayload(static_cast<int>(state.range(0)));
  std::uint32_t version = 0;
  for (auto _ : state) {
    msg.version = ++version % 50 + 1;  // within what a peer could publish
    node.OnMap(msg);
  }
  state.counters["refused"] = static_cast<double>(node.stats().MapsRefused());
  state.counters["received"] = static_cast<double>(node.stats().maps_received);
}
BENCHMARK(BM_AgentReceivesPeerMap)
    ->Arg(200)
    ->Arg(static_cast<int>(kMapCodecMaxLandmarks))
    ->Unit(benchmark::kMicrosecond);

// What decoding the 100 000-landmark map would cost (the agent does not).
void BM_DecodeHugeMap(benchmark::State& state) {
  const std::vector<std::uint8_t> payload = RandomPayload(static_cast<int>(kMapCodecMaxLandmarks));
  for (auto _ : state) benchmark::DoNotOptimize(DecodeMap(payload));
}
BENCHMARK(BM_DecodeHugeMap)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace mapmesh
