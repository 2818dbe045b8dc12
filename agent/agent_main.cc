// mapmesh-agent: one robot's process. It wires AgentNode to DDS: sensor streams in, maps
// and status out, peers' maps in through the radio gate; on SIGTERM/SIGINT it writes its
// final maps and statistics and exits 0.

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>

#include "agent/agent_node.h"
#include "common/app/process.h"
#include "common/io/run_files.h"
#include "common/transport/session.h"
#include "common/transport/shutdown.h"
#include "common/transport/topics.h"
#include "common/transport/typed.h"

namespace mapmesh {
namespace {

namespace tp = transport;
using io::json;

// Sends the agent's messages through DDS writers.
class DdsOutput : public AgentOutput {
 public:
  explicit DdsOutput(const tp::Participant& p)
      : maps_(p, tp::kMapTopic, tp::MapQos()), status_(p, tp::kStatusTopic, tp::StatusQos()) {}
  void PublishMap(const MapMessage& msg) override { maps_.Write(msg); }
  void PublishStatus(const AgentStatus& status) override { status_.Write(status); }

 private:
  tp::Writer<MapMessage> maps_;
  tp::Writer<AgentStatus> status_;
};

json StatsJson(const AgentNode& node) {
  const AgentStats& s = node.stats();
  const SyncStats& sync = node.sync_stats();
  const MapperStats& m = node.mapper().stats();
  json rejected = json::object();
  for (int i = 1; i < kMapDecodeErrorCount; ++i) {
    rejected[std::string(ToString(static_cast<MapDecodeError>(i)))] = s.maps_rejected[i];
  }
  json from = json::object();
  for (const auto& [id, n] : s.maps_received_from) from[std::to_string(id)] = n;
  const Pose2 pose = node.Pose();
  return {{"id", node.id()},
          {"processed_until", node.processed_until()},
          {"frame_origin_stamp", node.frame_origin_stamp() ? json(*node.frame_origin_stamp()) : json()},
          {"pose", {pose.x, pose.y, pose.theta}},
          {"local_landmarks", node.LocalMap().size()},
          {"odom_processed", sync.odom_processed},
          {"odom_rejected", sync.odom_rejected},
          {"scans_processed", sync.scans_processed},
          {"scans_empty", sync.scans_empty},
          {"scans_rejected", sync.scans_rejected},
          {"scans_before_start", sync.scans_before_start},
          {"scans_late", sync.scans_late},
          {"scans_missing", sync.scans_missing},
          {"observations", {{"offered", m.observations},
                            {"associated", m.associated},
                            {"initialised", m.initialised},
                            {"tentative", m.tentative},
                            {"rejected_gate", m.rejected_gate},
                            {"ambiguous", m.ambiguous},
                            {"unidentified", m.unidentified},
                            {"out_of_range", m.out_of_range},
                            {"invalid", m.invalid},
                            {"failed_updates", m.failed_updates}}},
          {"maps_sent", s.maps_sent},
          {"bytes_sent", s.bytes_sent},
          {"maps_received", s.maps_received},
          {"bytes_received", s.bytes_received},
          {"maps_out_of_range", s.maps_out_of_range},
          {"maps_lost", s.maps_lost},
          {"maps_over_bandwidth", s.maps_over_bandwidth},
          {"maps_unknown_sender", s.maps_unknown_sender},
          {"maps_rejected", rejected},
          {"maps_received_from", from}};
}

void WriteOutputs(const AgentNode& node, const std::string& dir) {
  std::filesystem::create_directories(dir);
  const LandmarkMap local = node.LocalMap();
  io::WriteJsonAtomic(dir + "/local_map.json", io::MapToJson(local));
  // Until map fusion exists the global map is the clone of the local map.
  io::WriteJsonAtomic(dir + "/global_map.json", io::MapToJson(local));
  io::WriteJsonAtomic(dir + "/stats.json", StatsJson(node));
  json poses = json::array();
  for (const auto& p : node.trajectory()) poses.push_back({p.t, p.pose.x, p.pose.y, p.pose.theta});
  io::WriteJsonAtomic(dir + "/trajectory.json",
                      {{"frame_origin_stamp", node.frame_origin_stamp() ? json(*node.frame_origin_stamp()) : json()},
                       {"poses", poses}});
}

int Run(int argc, char** argv) {
  tp::ShutdownSignal shutdown;  // first: block SIGINT/SIGTERM before any thread starts

  CLI::App cli{"mapmesh-agent: one robot's SLAM and map-sharing process"};
  app::ProcessOptions po;
  std::string out_dir;
  int id = 0;
  unsigned incarnation = static_cast<unsigned>(::getpid());
  app::AddScenarioOptions(cli, po);
  cli.add_option("--id", id, "robot id this agent runs for")->required()->check(CLI::PositiveNumber);
  app::AddDdsOptions(cli, po, /*domain_required=*/true);
  cli.add_option("--out", out_dir, "directory for the final maps and stats (default agent_<id>)");
  cli.add_option("--incarnation", incarnation, "number identifying this start of the agent");
  if (auto code = app::ParseArgs(cli, "mapmesh-agent", argc, argv)) return *code;
  app::SetupLogging("agent " + std::to_string(id), po.log_level);
  if (out_dir.empty()) out_dir = "agent_" + std::to_string(id);

  const std::optional<Scenario> loaded = app::LoadScenarioOrReport("mapmesh-agent", po);
  if (!loaded) return 2;
  const Scenario& scenario = *loaded;
  if (!scenario.FindRobot(static_cast<RobotId>(id))) {
    std::fprintf(stderr, "mapmesh-agent: %s: robots: no robot with id %d in this run\n",
                 po.scenario_path.c_str(), id);
    return 2;
  }

  tp::Session session(po.domain, po.dds_config, app::DefaultDdsConfig());
  const tp::Participant& p = session.participant();
  const RobotId self = static_cast<RobotId>(id);
  tp::Reader<Odometry> odom(p, tp::OdomTopic(self), tp::SensorQos());
  tp::Reader<Scan> scans(p, tp::ScanTopic(self), tp::SensorQos());
  tp::Reader<RadioLinks> links(p, tp::kLinksTopic, tp::LinksQos());
  tp::Reader<MapMessage> maps(p, tp::kMapTopic, tp::MapQos());
  DdsOutput output(p);
  AgentNode node(scenario, self, incarnation, output);

  tp::GuardCondition stop(p);
  tp::WaitSet waitset(p);
  waitset.AttachReader(odom.raw(), 1);
  waitset.AttachReader(scans.raw(), 2);
  waitset.AttachReader(links.raw(), 3);
  waitset.AttachReader(maps.raw(), 4);
  waitset.AttachGuard(stop, 5);
  shutdown.Watch(&stop);
  spdlog::info("up: scenario {} domain {} config {} incarnation {}", scenario.name, po.domain,
               session.config_used(), incarnation);

  // Status also goes out on a wall-clock beat: the feeder learns we exist before any data,
  // and a lost best-effort status never stalls lockstep for long.
  using Clock = std::chrono::steady_clock;
  constexpr auto kStatusBeat = std::chrono::milliseconds(200);
  output.PublishStatus(node.Status());
  auto next_beat = Clock::now() + kStatusBeat;
  while (!shutdown.requested()) {
    waitset.Wait(0.1);
    for (const auto& s : links.Take()) {
      if (s.valid) node.OnLinks(s.value);
    }
    for (const auto& s : scans.Take()) {
      if (s.valid) node.OnScan(s.value);
    }
    for (const auto& s : odom.Take()) {
      if (s.valid) node.OnOdometry(s.value);
    }
    for (const auto& s : maps.Take()) {
      if (s.valid) node.OnMap(s.value);
    }
    if (Clock::now() >= next_beat) {
      output.PublishStatus(node.Status());
      next_beat = Clock::now() + kStatusBeat;
    }
  }
  spdlog::info("signal {}: writing outputs to {}", shutdown.signal(), out_dir);
  WriteOutputs(node, out_dir);
  const AgentStats& st = node.stats();
  spdlog::info("done: t={:.1f}s odom={} scans={} landmarks={} maps_received={} maps_dropped={}",
               node.processed_until(), node.sync_stats().odom_processed, node.sync_stats().scans_processed,
               node.LocalMap().size(), st.maps_received, st.MapsDropped());
  return 0;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-agent", [&] { return mapmesh::Run(argc, argv); });
}
