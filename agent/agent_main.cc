// mapmesh-agent: one robot's process. It wires AgentNode to DDS: sensor streams in, maps
// and status out, peers' maps in through the radio gate (agent_dds.h); on SIGTERM/SIGINT/SIGHUP
// it writes its final maps and statistics (agent_outputs.h) and exits 0.

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <optional>
#include <utility>

#include "agent/agent_dds.h"
#include "agent/agent_node.h"
#include "agent/agent_outputs.h"
#include "agent/agent_setup.h"
#include "common/app/process.h"
#include "common/io/checkpoint.h"
#include "common/io/run_files.h"
#include "common/transport/oversize_counter.h"
#include "common/transport/session.h"
#include "common/transport/shutdown.h"
#include "common/transport/submap_signer.h"

namespace mapmesh {
namespace {

namespace tp = transport;

struct AgentArgs {
  app::ProcessOptions process;
  std::string out_dir;
  int id = 0;
  unsigned incarnation = static_cast<unsigned>(::getpid());
  bool resume = false;
  std::string peer_certificates;
};

// The command line; nullopt and the exit code in *code when it is not a run (--help, an error).
std::optional<AgentArgs> ParseAgentArgs(int argc, char** argv, int* code) {
  CLI::App cli{"mapmesh-agent: one robot's SLAM and map-sharing process"};
  AgentArgs a;
  app::AddScenarioOptions(cli, a.process);
  cli.add_option("--id", a.id, "robot id this agent runs for")->required()->check(CLI::PositiveNumber);
  app::AddDdsOptions(cli, a.process, /*domain_required=*/true);
  cli.add_option("--out", a.out_dir, "directory for the final maps and stats (default agent_<id>)");
  cli.add_option("--incarnation", a.incarnation, "number identifying this start of the agent");
  cli.add_flag(
      "--resume", a.resume,
      "restart from OUT/checkpoint.json: re-merge what the earlier incarnation knew (it starts a new map frame)");
  cli.add_option("--peer-certificates", a.peer_certificates,
                 "secure runs: the directory of every robot's certificate, agent<id>.pem, which its submaps' "
                 "signatures are checked with (default: the directory of this agent's own certificate)");
  if (auto exit = app::ParseArgs(cli, "mapmesh-agent", argc, argv)) {
    *code = *exit;
    return std::nullopt;
  }
  if (a.out_dir.empty()) a.out_dir = "agent_" + std::to_string(a.id);
  return a;
}

// --resume: the checkpoint, validated before any DDS entity exists, within the bounds a peer's
// map must keep (the world's extent, the run's end as sensor stamps). A missing one is a fresh
// start (nullopt); a bad one is one line and false.
bool LoadResume(const Scenario& scenario, RobotId self, const AgentArgs& a, std::optional<AgentCheckpoint>* out) {
  const std::string path = a.out_dir + "/checkpoint.json";
  io::CheckpointLimits limits;
  limits.max_abs_coordinate_m = scenario.agent.peer_limits.world_radius_m;
  limits.max_stamp_s = AgentRunFor(scenario, self).end_s + scenario.agent.max_stamp_jump_s;
  limits.submap_limits = scenario.agent.peer_limits;
  io::CheckpointLoad loaded = io::LoadCheckpoint(path, self, a.incarnation, limits);
  if (loaded.missing) {
    spdlog::warn("--resume: no checkpoint at {}; starting afresh", path);
    return true;
  }
  if (!loaded.ok()) {
    std::fprintf(stderr, "mapmesh-agent: %s\n", loaded.error.c_str());
    return false;
  }
  *out = std::move(loaded.checkpoint);
  return true;
}

// Secure runs: submaps signed by their robot and checked at every receiver (issue R3). nullptr
// and *why when this agent's credentials cannot sign.
std::unique_ptr<tp::SubmapSigner> MakeSigner(const tp::Session& session, RobotId self, const AgentRun& run,
                                             const std::string& peer_certificates, std::string* why) {
  std::unique_ptr<tp::SubmapSigner> signer = tp::SubmapSigner::Make(*session.security(), self, peer_certificates, why);
  if (!signer) return nullptr;
  for (RobotId r : run.robots) {
    if (r == self) continue;
    if (const std::optional<std::string> problem = signer->PeerProblem(r))
      spdlog::warn("robot {}'s submaps will be refused (unknown_signer): {}", r, *problem);
  }
  return signer;
}

// The agent's checkpoint and its outputs beside it, each warning of what a checkpoint leaves
// out once.
class Saver {
 public:
  Saver(const AgentNode& node, const AgentReaders& readers, std::string dir)
      : node_(node), readers_(readers), dir_(std::move(dir)) {}
  const OutputHealth& health() const { return health_; }

  // At a checkpoint: both, until a write first fails.
  void Checkpoint() {
    if (health_.stopped_at) return;
    try {
      SaveCheckpoint();
      WriteOutputs(node_, dir_, readers_.Counts(), health_, /*final=*/false);
    } catch (const io::WriteError& e) {
      Failed(e);
    }
  }
  // At the end: tried even after a failure (the disk may have room again); the error if not.
  std::optional<io::WriteError> Final(bool checkpoint) {
    try {
      WriteOutputs(node_, dir_, readers_.Counts(), health_, /*final=*/true);
      if (checkpoint) SaveCheckpoint();
    } catch (const io::WriteError& e) {
      Failed(e);
      return e;
    }
    return std::nullopt;
  }

 private:
  void Failed(const io::WriteError& e) {
    if (health_.Failed(e, node_.processed_until()))
      spdlog::error("{}: snapshots and checkpoints stop here (t={:.1f}s); mapping goes on (stats.json outputs)",
                    health_.reason, *health_.stopped_at);
  }
  void SaveCheckpoint() {
    std::size_t left_out = 0, submaps_left_out = 0;
    io::WriteJsonAtomic(dir_ + "/checkpoint.json",
                        io::CheckpointToJson(node_.Checkpoint(&left_out, &submaps_left_out)));
    if (left_out > 0 && !warned_left_out_) {
      spdlog::warn(
          "checkpoint: {} oldest earlier incarnations never re-merged are left out (a checkpoint holds {} at most)",
          left_out, io::CheckpointLimits{}.max_earlier);
      warned_left_out_ = true;
    }
    if (submaps_left_out > 0 && !warned_submaps_left_out_) {
      spdlog::warn("checkpoint: {} of the submaps held are left out (a checkpoint holds {} at most, {} MiB)",
                   submaps_left_out, io::CheckpointLimits{}.max_submaps, io::CheckpointLimits{}.max_submap_bytes >> 20);
      warned_submaps_left_out_ = true;
    }
  }

  const AgentNode& node_;
  const AgentReaders& readers_;
  const std::string dir_;
  OutputHealth health_;
  bool warned_left_out_ = false, warned_submaps_left_out_ = false;
};

double MonotonicS() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int Run(int argc, char** argv) {
  tp::ShutdownSignal shutdown;  // first: block SIGINT/SIGTERM/SIGHUP before any thread starts
  int code = 0;
  const std::optional<AgentArgs> args = ParseAgentArgs(argc, argv, &code);
  if (!args) return code;
  const app::ProcessOptions& po = args->process;
  app::SetupLogging("agent " + std::to_string(args->id), po.log_level);
  const std::optional<Scenario> loaded = app::LoadScenarioOrReport("mapmesh-agent", po);
  if (!loaded) return 2;
  const Scenario& scenario = *loaded;
  const RobotId self = static_cast<RobotId>(args->id);
  if (!scenario.FindRobot(self)) {
    std::fprintf(stderr, "mapmesh-agent: %s: robots: no robot with id %d in this run\n", po.scenario_path.c_str(),
                 args->id);
    return 2;
  }
  std::optional<AgentCheckpoint> checkpoint;
  if (args->resume && !LoadResume(scenario, self, *args, &checkpoint)) return 2;

  const AgentRun run = AgentRunFor(scenario, self);
  // A sample longer than any the run's agents send is dropped by the transport before it costs
  // memory (issue R3: a hostile 4 MB map took 23 MB of an agent's 16 MB before the inbox refused it).
  const std::size_t max_sample_bytes = AgentNode::MaxSampleBytes(scenario.agent, run);
  const tp::OversizeCounter oversize;  // before the session: Cyclone's drops counted from the start
  tp::Session session(po.domain, po.dds_config, app::DefaultDdsConfig(), max_sample_bytes);
  spdlog::info("samples beyond {} bytes dropped by the transport (Cyclone MaxSampleSize)", max_sample_bytes);
  const tp::Participant& p = session.participant();
  const double lease_s = scenario.agent.LivelinessLeaseS(scenario.robots.size());
  const bool lockstep = run.exchange_ticks;
  AgentReaders readers(p, self, lease_s, lockstep, oversize, max_sample_bytes);
  DdsOutput output(p, lease_s, self, lockstep);
  AgentNode node(scenario.agent, run, self, args->incarnation, output);
  std::unique_ptr<tp::SubmapSigner> signer;
  if (session.security()) {
    std::string why;
    if (!(signer = MakeSigner(session, self, run, args->peer_certificates, &why))) {
      std::fprintf(stderr, "mapmesh-agent: %s\n", why.c_str());
      return 2;
    }
    node.SetSubmapOrigin(signer.get());
  }
  if (checkpoint) {
    node.Resume(*checkpoint);
    spdlog::info(
        "resumed incarnation {} (t={:.1f}s, {} local and {} global landmarks, {} earlier incarnations, {} submaps)",
        checkpoint->incarnation, checkpoint->processed_until, checkpoint->local.size(), checkpoint->global.size(),
        checkpoint->earlier.size(), checkpoint->submaps.size());
    checkpoint.reset();
  }
  const double checkpoint_period = scenario.agent.checkpoint_period_s;
  double next_checkpoint = checkpoint_period;

  tp::GuardCondition stop(p);
  tp::WaitSet waitset(p);
  readers.Attach(waitset);
  waitset.AttachGuard(stop, 5);
  shutdown.Watch(&stop);
  spdlog::info("up: scenario {} domain {} config {} incarnation {} liveliness lease {} s", scenario.name, po.domain,
               session.config_used(), args->incarnation, lease_s);

  // Status also goes out on a wall-clock beat: the feeder learns we exist before any data,
  // and a lost best-effort status never stalls lockstep for long.
  using Clock = std::chrono::steady_clock;
  constexpr auto kStatusBeat = std::chrono::milliseconds(200);
  output.SendStatus(node.Status());
  auto next_beat = Clock::now() + kStatusBeat;
  PeerEventLog peer_events;
  InputWatch input_watch;
  Saver saver(node, readers, args->out_dir);
  while (!shutdown.requested()) {
    double wait_s = 0.1;
    if (const auto due = output.RepeatDue()) {
      wait_s = std::clamp(std::chrono::duration<double>(*due - Clock::now()).count(), 0.0, wait_s);
    }
    waitset.Wait(wait_s);
    readers.Pump(node);
    for (const std::string& line : peer_events.Update(node)) spdlog::info("{}", line);
    if (const std::optional<std::string> line = input_watch.Check(node, MonotonicS())) spdlog::warn("{}", *line);
    // In lockstep the checkpoints are taken at ticks, so that their contents do not depend on
    // when this loop woke up; in real time every checkpoint period of processed data.
    if (lockstep ? node.TakeCheckpointDue() : checkpoint_period > 0 && node.processed_until() >= next_checkpoint) {
      saver.Checkpoint();
      next_checkpoint = node.processed_until() + checkpoint_period;
    }
    if (const auto due = output.RepeatDue(); due && Clock::now() >= *due) {
      output.SendStatus(node.Status());
      output.RepeatDone();
    }
    if (Clock::now() >= next_beat) {
      output.SendStatus(node.Status());
      next_beat = Clock::now() + kStatusBeat;
    }
  }
  // What was delivered before the signal is counted too (a realtime run's tail), so that the
  // feeder's count of what it sent equals what arrived plus what was lost.
  readers.Pump(node);
  spdlog::info("signal {}: writing outputs to {}", shutdown.signal(), args->out_dir);
  const std::optional<io::WriteError> final_failure = saver.Final(checkpoint_period > 0);
  const AgentStats& st = node.stats();
  spdlog::info("done: t={:.1f}s odom={} scans={} landmarks={} global={} maps_received={} maps_dropped={}",
               node.processed_until(), node.sync_stats().odom_processed, node.sync_stats().scans_processed,
               node.LocalMap().size(), node.global().map.size(), st.maps_received, st.MapsDropped());
  const OutputHealth& health = saver.health();
  if (health.stopped_at) {
    spdlog::warn("snapshots and checkpoints had stopped at t={:.1f}s ({}); {} writes failed", *health.stopped_at,
                 health.reason, health.write_failures);
  }
  if (final_failure) {
    std::fprintf(stderr, "mapmesh-agent: %s: final outputs not written\n", final_failure->what());
    return app::kExitWriteFailed;
  }
  return 0;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-agent", [&] { return mapmesh::Run(argc, argv); });
}
