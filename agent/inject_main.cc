// mapmesh-inject: a fault injector for experiments and tests. It joins a run's DDS domain and
// publishes bad map messages and forged sensor data and links made by MapInjector
// (map_injector.h lists the cases): every --period-s of wall time, one message of each chosen
// case (its claimed robot in turn). Each map is written and its instance unregistered at once,
// so the injector never keeps a dead agent's map instance alive. On SIGINT/SIGTERM (or after
// --duration-s) it writes --report: what it sent, per case and claimed sender.

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>

#include "agent/map_injector.h"
#include "common/app/process.h"
#include "common/io/run_files.h"
#include "common/transport/session.h"
#include "common/transport/shutdown.h"
#include "common/transport/submap_signer.h"
#include "common/transport/topics.h"
#include "common/transport/typed.h"

namespace mapmesh {
namespace {

namespace tp = transport;
using io::json;

// {"unknown_id": N, "faulty_incarnation": I, "faulty_honest_maps": n,
//  "heard": {"id": {"maps": n, "closed_submap": b}}, "cases": {case: {"sent": n, "by_sender": {"id": n}}}}
json ReportJson(const MapInjector& injector) {
  json cases = json::object();
  for (const std::string& c : injector.cases()) {
    json by = json::object();
    int total = 0;
    if (const auto it = injector.sent().find(c); it != injector.sent().end()) {
      for (const auto& [sender, n] : it->second) {
        by[std::to_string(sender)] = n;
        total += n;
      }
    }
    cases[c] = {{"sent", total}, {"by_sender", by}};
  }
  json heard = json::object();
  for (const auto& [robot, h] : injector.heard_from()) {
    heard[std::to_string(robot)] = {{"maps", h.maps}, {"closed_submap", h.closed_submap}};
  }
  return {{"unknown_id", injector.unknown_id()},
          {"heard", heard},
          {"faulty_incarnation", kInjectFaultyIncarnation},
          {"faulty_honest_maps", injector.honest_sent()},
          {"cases", cases}};
}

int Run(int argc, char** argv) {
  tp::ShutdownSignal shutdown;  // first: block SIGINT/SIGTERM before any thread starts

  CLI::App cli{"mapmesh-inject: publish malformed, stale, foreign and wrong maps into a run's DDS domain"};
  cli.footer(
      "Cases: truncated, oversized, count_above_limit, bad_magic, unknown_version, non_finite, bad_covariance, "
      "duplicate_id, bad_header, out_of_bounds (payloads every agent must refuse, one reason each), stale_version (an older "
      "version of a robot's map), unknown_sender (a map from a robot not in the run), shuffled (a robot's map "
      "with its coordinates shuffled, as its next version: alignment verification must refuse it), "
      "odometry_stamp (odometry stamped 1e9 s), far_reading (a scan reading 30 km away, numbered 999999), links_stamp (a links table "
      "stamped 1e300 s), links_ahead (a links table linking everyone, stamped 15 s ahead of the agents, from a writer "
      "that is not the feeder's), version_jump (a robot's map under version 0xFFFFFFF0), huge_map (a valid map of 100 000 "
      "landmarks, one turn in ten), tick_flood (maps at far ticks, from a robot not in the run, with 1000 sightings), "
      "forged_submaps (a robot's next submaps, landmarks moved, on a stale copy of another's map), ghost_incarnation "
      "(a robot's submap under an incarnation never run, and one opened at -1e9 s, on the same carrier), forged_relay "
      "(forged_submaps' forgeries on the next robot's next map key, sent before its own; under DDS Security signed "
      "with the injector's identity, and with --inject-identity agentN carried on a map claiming robot N), huge_submaps (valid 500-landmark submaps, 2 MB each, two per message, under a "
      "robot's identity at new indices, on forged_relay's carrier). "
      "scripts/swarm run --inject CASES starts it alongside a run.");
  app::ProcessOptions po;
  std::string cases_text = "all", report_path;
  double period_s = 0.2, duration_s = 0.0, sim_period_s = 0.0;
  unsigned unknown_id = 0;
  std::optional<std::uint64_t> seed;
  app::AddScenarioOptions(cli, po);
  app::AddDdsOptions(cli, po, /*domain_required=*/false);
  cli.add_option("--cases", cases_text, "'all' or a comma-separated list of cases")->capture_default_str();
  cli.add_option("--period-s", period_s, "wall seconds between two messages")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  cli.add_option("--sim-period-s", sim_period_s,
                 "instead of --period-s: scenario seconds between two messages, by the latest time the agents "
                 "report (lockstep: the same number of messages over a run whatever the host's load)")
      ->check(CLI::PositiveNumber);
  cli.add_option("--duration-s", duration_s, "stop after this many wall seconds (0: at SIGINT/SIGTERM)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cli.add_option("--unknown-id", unknown_id, "robot id of unknown_sender maps (default: the largest id + 1000)");
  cli.add_option("--seed", seed, "seed of the random maps and shuffles (default: the scenario's)");
  unsigned as_robot = 0;
  cli.add_option("--as-robot", as_robot,
                 "write every map in robot N's DDS partition, whatever robot it claims (an impersonator holding N's "
                 "certificate; agents refuse a map whose robot is not its partition's); default: each claimed "
                 "robot's own partition");
  bool check = false;
  cli.add_flag("--check", check, "only validate the arguments and the scenario, then exit");
  cli.add_option("--report", report_path, "write what was sent, per case and sender, to this JSON file at exit");
  if (auto code = app::ParseArgs(cli, "mapmesh-inject", argc, argv)) return *code;
  app::SetupLogging("inject", po.log_level);
  const std::optional<std::vector<std::string>> cases = ParseInjectCases(cases_text);
  if (!cases) {
    std::string names;
    for (const std::string& c : AllInjectCases()) names += ", " + c;
    std::fprintf(stderr, "mapmesh-inject: --cases %s: expected all or a comma-separated list of: %s\n",
                 cases_text.c_str(), names.substr(2).c_str());
    return 2;
  }
  const std::optional<Scenario> loaded = app::LoadScenarioOrReport("mapmesh-inject", po);
  if (!loaded) return 2;
  RobotId largest = 0;
  for (const RobotSpec& r : loaded->robots) largest = std::max(largest, r.id);
  if (unknown_id == 0) unknown_id = largest + 1000;
  if (loaded->FindRobot(unknown_id)) {
    std::fprintf(stderr, "mapmesh-inject: --unknown-id %u: robot %u is in this run\n", unknown_id, unknown_id);
    return 2;
  }

  if (check) return 0;
  if (po.domain < 0) {
    std::fprintf(stderr, "mapmesh-inject: --domain is required (the run's DDS domain)\n");
    return 2;
  }

  tp::Session session(po.domain, po.dds_config, app::DefaultDdsConfig());
  const tp::Participant& p = session.participant();
  const double lease_s = loaded->agent.LivelinessLeaseS(loaded->robots.size());
  // The run's map QoS: in lockstep the agents' readers are reliable and transient-local.
  const bool lockstep = loaded->feeder.pace == Pace::kLockstep;
  tp::Reader<MapMessage> maps(p, tp::kMapTopic, tp::MapQosFor(lockstep, lease_s).Partition(tp::kEveryRobotPartition));
  tp::Reader<AgentStatus> status(p, tp::kStatusTopic, tp::StatusQos(lease_s).Partition(tp::kEveryRobotPartition));
  // Writers for every robot are made up front (so that readers have matched them before the
  // first message). Under DDS Security a participant's own permissions may forbid one
  // (dds_create_writer fails): what it would have written is counted as denied.
  std::map<RobotId, std::unique_ptr<tp::Writer<MapMessage>>> out;  // by partition robot
  std::unique_ptr<tp::Writer<RadioLinks>> links;
  std::map<RobotId, std::unique_ptr<tp::Writer<Odometry>>> odom;
  std::map<RobotId, std::unique_ptr<tp::Writer<Scan>>> scans;
  std::map<std::string, int> denied;  // messages not sent, by topic
  auto make = [&](auto& slot, const std::string& topic, auto create) {
    try {
      slot = create();
    } catch (const tp::DdsError& e) {
      spdlog::warn("cannot write {}: {}", topic, e.what());
    }
  };
  auto map_topic = [](RobotId part) { return std::string(tp::kMapTopic) + "@" + tp::RobotPartition(part); };
  std::vector<RobotId> partitions{as_robot ? static_cast<RobotId>(as_robot) : static_cast<RobotId>(unknown_id)};
  for (const RobotSpec& r : loaded->robots) {
    if (!as_robot) partitions.push_back(r.id);
    make(odom[r.id], tp::OdomTopic(r.id),
         [&] { return std::make_unique<tp::Writer<Odometry>>(p, tp::OdomTopic(r.id), tp::SensorQos()); });
    make(scans[r.id], tp::ScanTopic(r.id),
         [&] { return std::make_unique<tp::Writer<Scan>>(p, tp::ScanTopic(r.id), tp::SensorQos()); });
  }
  for (RobotId part : partitions) {
    make(out[part], map_topic(part), [&] {
      return std::make_unique<tp::Writer<MapMessage>>(
          p, tp::kMapTopic, tp::MapQosFor(lockstep, lease_s).Partition(tp::RobotPartition(part)));
    });
  }
  make(links, tp::kLinksTopic,
       [&] { return std::make_unique<tp::Writer<RadioLinks>>(p, tp::kLinksTopic, tp::LinksQos()); });
  auto use = [&](auto& slot, const std::string& topic) -> decltype(slot.get()) {
    if (!slot) ++denied[topic];
    return slot.get();
  };
  std::vector<RobotId> robots;
  for (const RobotSpec& r : loaded->robots) {
    if (r.id != as_robot) robots.push_back(r.id);  // an impersonator claims only the others
  }
  MapInjector injector(robots, *cases, unknown_id, seed.value_or(loaded->seed));
  if (as_robot) injector.ActAs(static_cast<RobotId>(as_robot));
  tp::Reader<ExchangeTick> ticks(p, tp::kTickTopic, tp::FeederTopicReader(tp::TickQos()));
  // Under DDS Security its forged submaps carry its own identity's signature (issue R3).
  std::unique_ptr<tp::SubmapSigner> signer;
  if (session.security()) {
    std::string why;
    signer = tp::SubmapSigner::Make(*session.security(), std::nullopt, "", &why);
    if (!signer) spdlog::warn("forged submaps go unsigned: {}", why);
  }
  if (signer) injector.SignWith([&signer](std::span<const std::uint8_t> b) { return signer->Sign(b); });
  tp::GuardCondition stop(p);
  tp::WaitSet waitset(p);
  waitset.AttachReader(maps.raw(), 1);
  waitset.AttachReader(status.raw(), 2);
  waitset.AttachGuard(stop, 3);
  shutdown.Watch(&stop);
  spdlog::info("up: domain {} cases {} period {:.3f}s unknown id {}", po.domain, cases->size(), period_s, unknown_id);

  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(period_s));
  auto next = start + period;
  int sent = 0;
  double sim_next = sim_period_s;  // --sim-period-s: the scenario time of the next messages
  double reported = 0.0;           // the latest scenario time an agent reported
  int sim_due = 0;                 // batches due by the scenario time, not yet sent
  while (!shutdown.requested()) {
    if (duration_s > 0 && Clock::now() - start >= std::chrono::duration<double>(duration_s)) break;
    waitset.Wait(sim_due > 0 ? 0.0 : std::max(0.0, std::chrono::duration<double>(next - Clock::now()).count()));
    for (const auto& s : maps.Take()) {
      if (s.valid) injector.OnMap(s.value);
    }
    for (const auto& s : ticks.Take()) {
      if (s.valid) injector.OnTick(s.value);
    }
    for (const auto& s : status.Take()) {
      if (!s.valid) continue;
      injector.OnStatus(s.value);
      reported = std::max(reported, s.value.processed_until);
    }
    if (sim_period_s > 0) {
      for (; sim_next <= reported; sim_next += sim_period_s) ++sim_due;
      if (Clock::now() >= next) next += period;  // (wakes to read, at the wall period)
      if (sim_due == 0) continue;
      --sim_due;
    } else {
      if (Clock::now() < next) continue;
      next += period;
    }
    // One message of each case per period: a case's pace does not depend on how many others run.
    for (std::size_t k = 0; k < cases->size(); ++k) {
      const std::optional<InjectedMessage> m = injector.Next();
      if (!m) break;
      std::visit(
          [&](const auto& x) {
            using T = std::decay_t<decltype(x)>;
            if constexpr (std::is_same_v<T, MapMessage>) {
              const RobotId part = as_robot ? static_cast<RobotId>(as_robot) : x.robot_id;
              if (auto* w = use(out[part], map_topic(part))) w->WriteAndUnregister(x);
            } else if constexpr (std::is_same_v<T, Odometry>) {
              if (auto* w = use(odom[x.robot_id], tp::OdomTopic(x.robot_id))) w->Write(x);
            } else if constexpr (std::is_same_v<T, Scan>) {
              if (auto* w = use(scans[x.robot_id], tp::ScanTopic(x.robot_id))) w->Write(x);
            } else {
              if (auto* w = use(links, tp::kLinksTopic)) w->Write(x);
            }
          },
          *m);
      ++sent;
    }
  }
  spdlog::info("done: {} messages sent", sent);
  if (!report_path.empty()) {
    json report = ReportJson(injector);
    report["denied_by_own_permissions"] = denied;
    // Readers that ever matched each writer: 0 where DDS Security kept every reader from it.
    json matched = json::object();
    for (const auto& [part, w] : out)
      if (w) matched[map_topic(part)] = w->raw().TotalMatchedReaders();
    for (const auto& [id, w] : odom)
      if (w) matched[tp::OdomTopic(id)] = w->raw().TotalMatchedReaders();
    for (const auto& [id, w] : scans)
      if (w) matched[tp::ScanTopic(id)] = w->raw().TotalMatchedReaders();
    if (links) matched[tp::kLinksTopic] = links->raw().TotalMatchedReaders();
    report["readers_matched"] = matched;
    io::WriteJsonAtomic(report_path, report);
  }
  return 0;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-inject", [&] { return mapmesh::Run(argc, argv); });
}
