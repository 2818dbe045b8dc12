// mapmesh-feeder: plays the world of a scenario over DDS (odometry, scans, radio links and
// ground truth), paced in lockstep with the agents or in real time, and writes truth.json.
// With --events it prints one JSON object per line on stdout (progress, holds, the end);
// with --control it reads launcher commands on stdin ("dead ID", "expect ID", "continue").

#include <poll.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "common/app/process.h"
#include "common/io/run_files.h"
#include "common/transport/session.h"
#include "common/transport/shutdown.h"
#include "common/transport/topics.h"
#include "common/transport/typed.h"
#include "common/types/scenario_limits.h"
#include "sim_feeder/lockstep_pacer.h"
#include "sim_feeder/play_record.h"
#include "sim_feeder/recording.h"
#include "sim_feeder/sources.h"

namespace mapmesh {
namespace {

namespace tp = transport;
using io::json;

// The scenario's fault schedule for the launcher, which carries it out (scripts/mapmesh/run.py).
json FaultsToJson(const FaultOptions& f) {
  json kills = json::array(), restarts = json::array(), pauses = json::array();
  for (const FaultEvent& e : f.events) {
    switch (e.kind) {
      case FaultEvent::Kind::kKill: kills.push_back({{"id", e.id}, {"t", e.t}}); break;
      case FaultEvent::Kind::kRestart: restarts.push_back({{"id", e.id}, {"t", e.t}}); break;
      case FaultEvent::Kind::kPause: pauses.push_back({{"id", e.id}, {"t", e.t}, {"seconds", e.seconds}}); break;
    }
  }
  return {{"kill", kills},
          {"restart", restarts},
          {"pause", pauses},
          {"inject", f.inject},
          {"inject_period_s", f.inject_period_s}};
}

using Clock = std::chrono::steady_clock;

// Exit codes: 0 done, 1 internal error, 2 bad arguments or scenario, 3 agents failed to
// start, 130 interrupted.
constexpr int kExitStartup = 3;
constexpr int kExitInterrupted = 130;

// The state of a process on this host, from /proc.
ProcessState StateOf(int pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!stat || !std::getline(stat, line)) return ProcessState::kGone;
  // "pid (comm) S ...": the state follows the last ')' (comm may hold anything).
  const auto close = line.rfind(')');
  if (close == std::string::npos || close + 2 >= line.size()) return ProcessState::kGone;
  const char state = line[close + 2];
  if (state == 'Z' || state == 'X') return ProcessState::kGone;
  if (state == 'T' || state == 't') return ProcessState::kStopped;
  return ProcessState::kRunning;
}

double WallNow() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

class Interrupted : public std::runtime_error {
 public:
  Interrupted() : std::runtime_error("interrupted") {}
};

// Launcher commands arriving on stdin, read without blocking.
class ControlInput {
 public:
  explicit ControlInput(bool enabled) : enabled_(enabled) {}
  std::vector<ControlCommand> Poll() {
    std::vector<ControlCommand> out;
    if (!enabled_ || eof_) return out;
    pollfd pfd{STDIN_FILENO, POLLIN, 0};
    while (::poll(&pfd, 1, 0) > 0 && (pfd.revents & (POLLIN | POLLHUP))) {
      char buf[512];
      const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
      if (n <= 0) {
        eof_ = true;
        break;
      }
      pending_.append(buf, static_cast<std::size_t>(n));
    }
    std::size_t nl;
    while ((nl = pending_.find('\n')) != std::string::npos) {
      const std::string line = pending_.substr(0, nl);
      pending_.erase(0, nl + 1);
      if (auto c = ParseControl(line)) {
        out.push_back(*c);
      } else if (!line.empty()) {
        spdlog::warn("ignoring control line '{}'", line);
      }
    }
    return out;
  }
  bool enabled() const { return enabled_; }

 private:
  bool enabled_;
  bool eof_ = false;
  std::string pending_;
};

// Everything the feeder publishes and listens to.
struct Channels {
  Channels(const tp::Participant& p, const Scenario& sc)
      : links(p, tp::kLinksTopic, tp::FeederWriter(tp::LinksQos())),
        truth(p, tp::kTruthTopic, tp::TruthQos()),
        ticks(p, tp::kTickTopic, tp::FeederWriter(tp::TickQos())),
        status(p, tp::kStatusTopic,
               tp::StatusQos(sc.agent.LivelinessLeaseS(sc.robots.size())).Partition(tp::kEveryRobotPartition)),
        status_writers(status.raw()) {
    for (const RobotSpec& r : sc.robots) {
      odom.emplace(r.id, std::make_unique<tp::Writer<Odometry>>(p, tp::OdomTopic(r.id), tp::SensorQos()));
      scan.emplace(r.id, std::make_unique<tp::Writer<Scan>>(p, tp::ScanTopic(r.id), tp::SensorQos()));
    }
  }
  // Cumulative number of readers ever matched by both sensor writers of a robot (0 for a
  // robot not in the scenario).
  std::uint32_t TotalMatches(RobotId id) const {
    if (!odom.count(id)) return 0;
    return std::min(odom.at(id)->raw().TotalMatchedReaders(), scan.at(id)->raw().TotalMatchedReaders());
  }
  std::map<RobotId, std::unique_ptr<tp::Writer<Odometry>>> odom;
  std::map<RobotId, std::unique_ptr<tp::Writer<Scan>>> scan;
  tp::Writer<RadioLinks> links;
  tp::Writer<GroundTruth> truth;
  tp::Writer<ExchangeTick> ticks;
  tp::Reader<AgentStatus> status;
  tp::WriterPartitions status_writers;  // a status counts only from its robot's partition
};

// The feeder's DDS side around the pacer: reads what the agents and the launcher say, and
// waits (sleeping) while the pacer says to.
class Feeder {
 public:
  Feeder(const Scenario& sc, Channels& ch, LockstepPacer& pacer, ControlInput& control, tp::ShutdownSignal& shutdown,
         bool events)
      : sc_(sc), ch_(ch), pacer_(pacer), control_(control), shutdown_(shutdown), events_(events) {}

  // Reads statuses, liveliness changes, subscriptions, the processes of silent agents and
  // launcher commands.
  void Pump() {
    if (shutdown_.requested()) throw Interrupted();
    for (const auto& s : ch_.status.Take()) {
      const RobotId id = s.value.robot_id;
      if (s.valid && !tp::SpeaksFor(ch_.status_writers.Of(s.publication), id)) {
        spdlog::warn("refused a status claiming agent {} from a writer outside its partition", id);
        continue;
      }
      if (s.valid) {
        spdlog::trace("status {} inc {} t {:.2f}", id, s.value.incarnation, s.value.processed_until);
        if (pacer_.OnStatus(s.value)) spdlog::info("agent {} speaks again", id);
      }
      // The writer of that status instance is gone (liveliness expired or it was disposed): an
      // invalid sample says so, or the state of a last sample still unread.
      if (s.alive) continue;
      if (const std::optional<bool> exists = pacer_.OnStatusGone(id)) {
        spdlog::warn("agent {} lost (DDS liveliness){}", id, *exists ? "; its process exists: waiting for it" : "");
      }
    }
    for (RobotId id : pacer_.ReapSilent()) spdlog::warn("agent {}'s process is gone", id);
    for (const auto& [id, writer] : ch_.odom) {
      Resend(id, pacer_.OnMatches(id, ch_.TotalMatches(id)));
      Resend(id, pacer_.ReplayDue(id), /*replay=*/true);
    }
    for (const ControlCommand& c : control_.Poll()) {
      if (c.kind == ControlCommand::Kind::kStop) throw Interrupted();
      pacer_.OnControl(c, ch_.TotalMatches(c.id));
      if (c.kind == ControlCommand::Kind::kDead) spdlog::info("agent {} killed", c.id);
      if (c.kind == ControlCommand::Kind::kExpect) spdlog::info("agent {} restarting", c.id);
    }
  }

  // Waits until no agent is starting; returns the agents that did not come up in time.
  std::vector<RobotId> WaitForAgents(double timeout_s) {
    pacer_.BeginStartup(WallNow(), timeout_s);
    while (true) {
      Pump();
      if (auto failed = pacer_.PollStartup(WallNow())) return *failed;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }

  // Lockstep barrier: waits until every up agent has processed what was published to it.
  void WaitForBarrier() {
    pacer_.BeginBarrier(WallNow());
    double next_note = WallNow() + 10.0;
    while (true) {
      Pump();
      const LockstepPacer::BarrierPoll poll = pacer_.PollBarrier(WallNow());
      if (!poll.done && WallNow() >= next_note) {
        std::string who;
        for (RobotId id : poll.waiting) who += (who.empty() ? "" : ",") + std::to_string(id);
        spdlog::warn("barrier: still waiting for agents {} to process what was sent them", who);
        next_note = WallNow() + 10.0;
      }
      for (RobotId id : poll.stalled) {
        spdlog::error("agent {} made no progress for {:.0f} s; no longer waiting for it", id,
                      pacer_.options().stall_timeout_s);
      }
      if (poll.done) return;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }

  // The exchange tick of an exchange point (messages.h ExchangeTick): its exchange phase, then
  // its deliver phase, each sent and waited for until every live agent has answered.
  void Exchange(std::uint32_t index, double stamp) {
    ch_.ticks.Write(pacer_.BeginExchange(index, stamp, links_, WallNow()));
    WaitForTick();
    ch_.ticks.Write(pacer_.BeginDeliver(WallNow()));
    WaitForTick();
  }

  // Stops at a hold point until the launcher says continue, then waits for restarted agents.
  void Hold(double stamp) {
    Emit({{"event", "hold"}, {"t", stamp}});
    pacer_.BeginHold();
    while (!pacer_.HoldReleased()) {
      Pump();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    const std::uint64_t replayed = pacer_.replayed();
    for (RobotId id : WaitForAgents(sc_.feeder.startup_timeout_s)) {
      spdlog::error("restarted agent {} did not come up within {:.0f} s", id, sc_.feeder.startup_timeout_s);
      pacer_.GiveUp(id);
    }
    if (pacer_.replayed() > replayed) {
      spdlog::info("t={:.1f}s replayed {} sensor messages to restarted agents", stamp, pacer_.replayed() - replayed);
    }
  }

  // Sends a link table (the latest goes with the next exchange tick).
  void Publish(const RadioLinks& l) {
    ch_.links.Write(l);
    links_ = l;
  }

  void Publish(const Odometry& o) {
    ch_.odom.at(o.robot_id)->Write(o);
    pacer_.Published(o);
  }
  void Publish(const Scan& s) {
    ch_.scan.at(s.robot_id)->Write(s);
    pacer_.Published(s);
  }

  void Emit(const json& event) {
    if (!events_) return;
    std::fputs((event.dump() + "\n").c_str(), stdout);
    std::fflush(stdout);
  }

  json Progress(double stamp) const {
    std::uint64_t maps = 0;
    std::size_t aligned = 0;  // ordered pairs: agent A holds an alignment to B
    json alive = json::array();
    for (const AgentStatus& s : pacer_.tracker().Statuses()) {
      if (pacer_.tracker().IsUp(s.robot_id)) {
        alive.push_back(s.robot_id);
        maps += s.maps_received;
        aligned += s.peers_aligned.size();
      }
    }
    return {{"event", "progress"},        {"t", stamp},
            {"duration", sc_.duration_s}, {"alive", alive},
            {"maps_received", maps},      {"aligned_pairs", aligned}};
  }

 private:
  // Sensor messages sent again to an agent whose readers came back (see LockstepPacer).
  void Resend(RobotId id, const std::vector<SentLog::Message>& again, bool replay = false) {
    if (again.empty()) return;
    if (replay) {
      spdlog::debug("agent {}: replaying {} sensor messages of its stream", id, again.size());
    } else {
      spdlog::info("agent {} matched again: sending the {} sensor messages it has not processed", id, again.size());
    }
    for (const SentLog::Message& m : again) {
      if (const auto* o = std::get_if<Odometry>(&m)) {
        ch_.odom.at(id)->Write(*o);
      } else {
        ch_.scan.at(id)->Write(std::get<Scan>(m));
      }
    }
  }

  void WaitForTick() {
    double next_note = WallNow() + 10.0;
    while (true) {
      Pump();
      const LockstepPacer::TickPoll poll = pacer_.PollTick(WallNow());
      if (!poll.done && WallNow() >= next_note) {
        std::string who;
        for (RobotId id : poll.waiting) who += (who.empty() ? "" : ",") + std::to_string(id);
        spdlog::warn("exchange tick {} ({}): still waiting for agents {}", pacer_.tick().index,
                     pacer_.tick().phase == TickPhase::kExchange ? "exchange" : "deliver", who);
        next_note = WallNow() + 10.0;
      }
      for (RobotId id : poll.stalled) {
        spdlog::error("agent {} did not answer exchange tick {} for {:.0f} s; no longer waiting for it", id,
                      pacer_.tick().index, pacer_.options().stall_timeout_s);
      }
      if (poll.reissue) ch_.ticks.Write(pacer_.BeginDeliver(WallNow()));
      if (poll.done) return;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }

  const Scenario& sc_;
  Channels& ch_;
  LockstepPacer& pacer_;
  RadioLinks links_{-1.0, {}};
  ControlInput& control_;
  tp::ShutdownSignal& shutdown_;
  bool events_;
};

int Run(int argc, char** argv) {
  tp::ShutdownSignal shutdown;  // first: block SIGINT/SIGTERM/SIGHUP before any thread starts

  CLI::App cli{"mapmesh-feeder: simulates (or replays) the world and publishes it over DDS"};
  app::ProcessOptions po;
  std::string out_dir, pace, datasets, record_path;
  double rate = 0.0, stall_timeout_s = 120.0;
  bool check_only = false, events = false, control_enabled = false, no_dds = false;
  std::vector<double> holds;
  app::AddScenarioOptions(cli, po);
  app::AddDdsOptions(cli, po, /*domain_required=*/false);
  cli.add_option("--out", out_dir, "directory for truth.json and feeder.json (without it neither is written)");
  cli.add_option("--datasets", datasets,
                 "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets beside the sources)");
  std::vector<std::string> paces;
  for (const auto& c : kPaces) paces.emplace_back(c.name);
  cli.add_option("--pace", pace, "override feeder.pace")->check(CLI::IsMember(paces));
  cli.add_option("--rate", rate, "override feeder.realtime_factor")
      ->check(CLI::Range(limits::kMinRealtimeFactor, limits::kMaxRealtimeFactor));
  cli.add_option("--hold-at", holds, "with --control: pause at these scenario times until 'continue'");
  cli.add_option("--stall-timeout", stall_timeout_s, "lockstep: give up on an agent stuck this many wall seconds");
  cli.add_option("--record", record_path, "also write the whole stream to this file (see recording.h)");
  cli.add_flag("--no-dds", no_dds, "with --record: only generate and record, as fast as possible");
  cli.add_flag("--check", check_only, "validate the scenario (and read its dataset) and exit");
  cli.add_flag("--events", events, "print JSON events on stdout");
  cli.add_flag("--control", control_enabled, "read launcher commands on stdin");
  if (auto code = app::ParseArgs(cli, "mapmesh-feeder", argc, argv)) return *code;
  app::SetupLogging("feeder", po.log_level);

  std::optional<Scenario> loaded = app::LoadScenarioOrReport("mapmesh-feeder", po);
  if (!loaded) return 2;
  Scenario& sc = *loaded;
  if (!pace.empty()) sc.feeder.pace = *ParseChoice(kPaces, pace);
  if (rate > 0.0) sc.feeder.realtime_factor = rate;
  Feed feed;
  try {
    feed = MakeFeed(sc, ResolveDatasetsRoot(datasets, app::DefaultDatasetsRoot()));
  } catch (const std::exception& e) {  // ConfigError or DatasetError: one line
    std::fprintf(stderr, "mapmesh-feeder: %s\n", e.what());
    return 2;
  }
  FeedSource& source = *feed.source;
  std::vector<RobotId> ids;
  for (const auto& r : sc.robots) ids.push_back(r.id);
  if (check_only) {
    if (events) {
      std::printf("%s\n", json{{"event", "check"},
                               {"name", sc.name},
                               {"source", std::string(NameOf(kSourceTypes, sc.source.type))},
                               {"robots", ids},
                               {"landmarks", source.Truth().landmarks.size()},
                               {"duration", sc.duration_s},
                               {"pace", std::string(NameOf(kPaces, sc.feeder.pace))},
                               {"seed", sc.seed},
                               {"faults", FaultsToJson(sc.faults)},
                               {"resolved", io::ResolvedToJson(sc.resolved)}}
                              .dump()
                              .c_str());
    } else {
      std::printf("%s: ok: %zu robots, %zu landmarks, %.1f s\n", po.scenario_path.c_str(), sc.robots.size(),
                  source.Truth().landmarks.size(), sc.duration_s);
    }
    return 0;
  }
  if (no_dds && record_path.empty()) {
    std::fprintf(stderr, "mapmesh-feeder: --no-dds needs --record FILE (see --help)\n");
    return 2;
  }
  if (!no_dds && po.domain < 0) {
    std::fprintf(stderr, "mapmesh-feeder: --domain is required (see --help)\n");
    return 2;
  }
  if (!out_dir.empty()) std::filesystem::create_directories(out_dir);
  std::optional<RecordingWriter> recording;
  if (!record_path.empty()) recording.emplace(record_path);
  PlayRecord record(sc, source, feed.counts);
  const auto wall_start = Clock::now();

  if (no_dds) {
    while (!source.Done()) {
      const FeedBatch b = source.Next();
      recording->Write(b);
      record.Add(b);
      for (const Scan& s : b.scans) record.CountSent(s);
      for (const Odometry& o : b.odom) record.CountSent(o);
    }
    recording->Close();
    if (!out_dir.empty()) {
      record.Write(out_dir, source, std::chrono::duration<double>(Clock::now() - wall_start).count(), false);
    }
    return 0;
  }

  tp::Session session(po.domain, po.dds_config, app::DefaultDdsConfig());
  Channels ch(session.participant(), sc);
  const bool lockstep = sc.feeder.pace == Pace::kLockstep;
  LockstepPacer pacer(ids,
                      {lockstep, sc.feeder.lockstep_window_s, stall_timeout_s, holds,
                       lockstep ? sc.agent.exchange.map_publish_period_s : 0.0, sc.feeder.keep_streams,
                       // half what an agent takes ahead of its odometry: max_stamp_jump_s for scans,
                       // 30 s (SensorSync::kMaxScanWaitS) for odometry waiting for its scans
                       std::min(sc.agent.max_stamp_jump_s, 30.0) / 2.0},
                      StateOf);
  ControlInput control(control_enabled);
  shutdown.Watch(nullptr);
  Feeder feeder(sc, ch, pacer, control, shutdown, events);
  spdlog::info("scenario {} ({}): {} robots, {} landmarks, {:.1f} s, pace {}, domain {}", sc.name,
               NameOf(kSourceTypes, sc.source.type), sc.robots.size(), source.Truth().landmarks.size(), sc.duration_s,
               NameOf(kPaces, sc.feeder.pace), po.domain);

  int exit_code = 0;
  try {
    const auto failed = feeder.WaitForAgents(sc.feeder.startup_timeout_s);
    if (!failed.empty()) {
      std::string list;
      for (RobotId id : failed) list += (list.empty() ? "" : ",") + std::to_string(id);
      std::fprintf(stderr, "mapmesh-feeder: agents %s did not start within %.0f s\n", list.c_str(),
                   sc.feeder.startup_timeout_s);
      return kExitStartup;
    }
    feeder.Emit({{"event", "start"}, {"robots", ids}, {"duration", sc.duration_s}});
    auto last_progress = Clock::now() - std::chrono::seconds(10);
    auto play_start = Clock::now();
    auto publish_odom = [&](const Odometry& o) {
      feeder.Publish(o);
      record.CountSent(o);
    };
    while (!source.Done()) {
      const FeedBatch b = source.Next();
      if (recording) recording->Write(b);
      record.Add(b);
      const bool last = source.Done();
      if (!lockstep) {
        const auto due = play_start + std::chrono::duration_cast<Clock::duration>(
                                          std::chrono::duration<double>(b.stamp / sc.feeder.realtime_factor));
        while (Clock::now() < due) {
          feeder.Pump();
          std::this_thread::sleep_until(std::min(due, Clock::now() + std::chrono::milliseconds(20)));
        }
      }
      if (b.links) feeder.Publish(*b.links);
      for (const Scan& s : b.scans) {
        feeder.Publish(s);
        record.CountSent(s);
      }
      for (const GroundTruth& g : b.truth) ch.truth.Write(g);
      for (const Odometry& o : b.odom) {
        if (const std::optional<Odometry> now = pacer.Admit(o)) publish_odom(*now);
      }
      if (!pacer.IsBarrier(b.stamp, last)) continue;
      for (const Odometry& o : pacer.CloseWindow(b.stamp)) publish_odom(o);
      if (lockstep) feeder.WaitForBarrier();
      if (const std::optional<std::uint32_t> k = pacer.ExchangeDue(b.stamp)) {
        feeder.Exchange(*k, *k * sc.agent.exchange.map_publish_period_s);
      }
      feeder.Pump();
      if (Clock::now() - last_progress > std::chrono::milliseconds(500) || last) {
        feeder.Emit(feeder.Progress(b.stamp));
        last_progress = Clock::now();
      }
      const auto hold_start = Clock::now();
      for (int n = pacer.TakeHolds(b.stamp); n > 0; --n) {
        if (control.enabled()) feeder.Hold(b.stamp);
      }
      // Scenario time stands still at a hold (a restarted agent takes its replayed stream): in
      // real time the run goes on at its rate from where it stopped. Played as due from the
      // start, the time held came out as one burst after it, scans up to 22 s of scenario time
      // ahead of the odometry taken, which an agent refuses as implausible.
      play_start += Clock::now() - hold_start;
    }
    // A closing tick: every agent ends holding what its peers published last.
    if (const auto closing = pacer.ClosingExchange()) feeder.Exchange(closing->index, closing->stamp);
  } catch (const Interrupted&) {
    spdlog::warn("interrupted: writing what was played so far");
    exit_code = kExitInterrupted;
  }

  // Let the agents that are up acknowledge the tail of their streams before the writers go
  // away (a killed agent's reader stays matched until its lease ends; do not wait for it).
  for (RobotId id : pacer.tracker().Up()) {
    ch.odom.at(id)->raw().WaitForAcks(2.0);
    ch.scan.at(id)->raw().WaitForAcks(2.0);
  }
  if (recording) recording->Close();
  const double wall_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
  if (!out_dir.empty()) record.Write(out_dir, source, wall_s, exit_code != 0, pacer.resent(), pacer.replayed());
  feeder.Emit({{"event", "done"}, {"wall_s", wall_s}, {"interrupted", exit_code != 0}});
  spdlog::info("done in {:.1f} s wall", wall_s);
  return exit_code;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-feeder", [&] { return mapmesh::Run(argc, argv); });
}
