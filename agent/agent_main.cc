// mapmesh-agent: one robot's process. It wires AgentNode to DDS: sensor streams in, maps
// and status out, peers' maps in through the radio gate; on SIGTERM/SIGINT it writes its
// final maps and statistics and exits 0.

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <filesystem>

#include "agent/agent_node.h"
#include "common/config/config_error.h"
#include "common/config/scenario.h"
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
          {"odom_processed", s.odom_processed},
          {"odom_rejected", s.odom_rejected},
          {"scans_processed", s.scans_processed},
          {"scans_rejected", s.scans_rejected},
          {"scans_before_start", s.scans_before_start},
          {"scans_late", s.scans_late},
          {"scans_missing", s.scans_missing},
          {"maps_sent", s.maps_sent},
          {"bytes_sent", s.bytes_sent},
          {"maps_received", s.maps_received},
          {"bytes_received", s.bytes_received},
          {"maps_out_of_range", s.maps_out_of_range},
          {"maps_lost", s.maps_lost},
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
}

int Run(int argc, char** argv) {
  tp::ShutdownSignal shutdown;  // first: block SIGINT/SIGTERM before any thread starts

  CLI::App app{"mapmesh-agent: one robot's SLAM and map-sharing process"};
  std::string scenario_path, out_dir, dds_config, log_level = "info";
  int id = 0, domain = -1, agents = 0;
  unsigned incarnation = static_cast<unsigned>(::getpid());
  std::vector<std::string> sets;
  app.add_option("--scenario", scenario_path, "scenario YAML file")->required();
  app.add_option("--id", id, "robot id this agent runs for")->required()->check(CLI::PositiveNumber);
  app.add_option("--domain", domain, "DDS domain id (the launcher picks a free one)")
      ->required()->check(CLI::Range(0, 232));
  app.add_option("--agents", agents, "number of robots in the run (as given to the launcher)");
  app.add_option("--set", sets, "override a scenario key: key.path=value (repeatable)");
  app.add_option("--out", out_dir, "directory for the final maps and stats (default agent_<id>)");
  app.add_option("--dds-config", dds_config,
                 "Cyclone DDS XML config (default: CYCLONEDDS_URI, else the shipped loopback config)");
  app.add_option("--incarnation", incarnation, "number identifying this start of the agent");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);
    std::fprintf(stderr, "mapmesh-agent: %s (see --help)\n", e.what());
    return 2;
  }
  auto logger = spdlog::stderr_color_mt("agent");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%H:%M:%S.%e] [agent " + std::to_string(id) + "] [%l] %v");
  spdlog::set_level(spdlog::level::from_str(log_level));
  if (out_dir.empty()) out_dir = "agent_" + std::to_string(id);

  Scenario scenario;
  try {
    std::vector<ConfigOverride> overrides;
    for (const auto& s : sets) overrides.push_back(ParseOverride(s));
    scenario = LoadScenario(scenario_path, overrides, agents);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "mapmesh-agent: %s\n", e.what());
    return 2;
  }
  if (!scenario.FindRobot(static_cast<RobotId>(id))) {
    std::fprintf(stderr, "mapmesh-agent: %s: robots: no robot with id %d in this run\n",
                 scenario_path.c_str(), id);
    return 2;
  }

  tp::Session session(domain, dds_config, MAPMESH_SOURCE_DIR "/config/cyclonedds-loopback.xml");
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
  spdlog::info("up: scenario {} domain {} config {} incarnation {}", scenario.name, domain,
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
               node.processed_until(), st.odom_processed, st.scans_processed,
               node.LocalMap().size(), st.maps_received,
               st.maps_out_of_range + st.maps_lost + st.maps_unknown_sender + st.MapsRejected());
  return 0;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  try {
    return mapmesh::Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mapmesh-agent: %s\n", e.what());
    return 1;
  }
}
