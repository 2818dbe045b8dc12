#pragma once
// What an agent process writes about itself (docs/OUTPUTS.md): stats.json, its two maps, the
// snapshots and history.jsonl for plots over time, the last maps each peer sent, its trajectory;
// and the log lines that tell how its global map came to be and what input it refused.
//
// No DDS and no clock: what the process around the node counted (senders refused, samples the
// transport dropped, peers whose liveliness it lost) comes in as ShellCounts, and time as an
// argument. The files are the node's state alone, so two lockstep runs write the same bytes.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "agent/agent_node.h"
#include "common/io/run_files.h"

namespace mapmesh {

// What the process shell counted beside the node (agent_main.cc), for stats.json.
struct ShellCounts {
  std::map<RobotId, double> peers_lost_wall;           // when each peer's liveliness was lost (wall clock)
  std::map<RobotId, std::uint64_t> maps_impersonated;  // samples claiming a robot from outside its partition
  std::map<RobotId, std::uint64_t> sightings_impersonated;
  std::uint64_t links_not_from_feeder = 0;  // link tables and ticks not from the run's feeder
  std::uint64_t ticks_not_from_feeder = 0;
  std::uint64_t oversize_dropped = 0;  // samples the transport dropped for their size ...
  std::size_t max_sample_bytes = 0;    // ... beyond this (AgentNode::MaxSampleBytes)
};

// Whether the agent can still write its outputs. The first failed write (a full disk, an I/O
// error) stops its snapshots and checkpoints for the rest of the incarnation; mapping and the
// exchange go on, and the final outputs are tried once more.
struct OutputHealth {
  std::uint64_t write_failures = 0;
  std::optional<double> stopped_at;  // processed_until at the first failure
  std::string reason;                // that failure's "PATH: REASON"
  // Counts the failure; true for the first (the one to log).
  bool Failed(const io::WriteError& e, double t);
};

// stats.json: the node's counters and state, the shell's counts and the outputs' health.
io::json StatsJson(const AgentNode& node, const ShellCounts& shell, const OutputHealth& health);

// Writes the agent's maps, stats.json (with `final`), a snapshot of both maps, one line of
// history.jsonl and trajectory.json into dir; when final, also each peer's last maps (peers/).
// Written at every checkpoint too, so that an agent killed without warning leaves its last
// state behind. Throws io::WriteError.
void WriteOutputs(const AgentNode& node, const std::string& dir, const ShellCounts& shell, const OutputHealth& health,
                  bool final);

// One log line per alignment event (aligned, realigned, refuted, dropped, re-placed), so that
// the log tells how the global map came to be. Alignments change only when the agent publishes
// its maps (MapExchange::Update): the peers are compared only then.
class PeerEventLog {
 public:
  std::vector<std::string> Update(const AgentNode& node);

 private:
  std::map<PeerKey, PeerReport> last_;
  std::uint64_t updates_ = 0;  // the exchange's update the reports were taken at
};

// A warning line when the agent refuses input or cannot send its map: what and how many since
// the last line, at most one every 5 seconds (a flood of bad input must not flood the log), the
// counts looked at once a second. now_s: a monotonic clock's seconds.
class InputWatch {
 public:
  std::optional<std::string> Check(const AgentNode& node, double now_s);

 private:
  std::map<std::string, std::uint64_t> last_;
  double next_s_ = -1e300;
};

}  // namespace mapmesh
