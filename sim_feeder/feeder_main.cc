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
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "common/app/process.h"
#include "common/config/config_error.h"
#include "common/config/scenario_limits.h"
#include "common/io/run_files.h"
#include "common/transport/session.h"
#include "common/transport/shutdown.h"
#include "common/transport/topics.h"
#include "common/transport/typed.h"
#include "sim_feeder/agent_tracker.h"
#include "sim_feeder/recording.h"
#include "sim_feeder/sent_log.h"
#include "sim_feeder/sources.h"

namespace mapmesh {
namespace {

namespace tp = transport;
using io::json;
using Clock = std::chrono::steady_clock;

// Exit codes: 0 done, 1 internal error, 2 bad arguments or scenario, 3 agents failed to
// start, 130 interrupted.
constexpr int kExitStartup = 3;
constexpr int kExitInterrupted = 130;

// The state of a process on this host, from /proc: gone (or a zombie), stopped (SIGSTOP,
// traced), or anything else.
enum class ProcessState { kGone, kStopped, kRunning };
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
      : links(p, tp::kLinksTopic, tp::LinksQos()),
        truth(p, tp::kTruthTopic, tp::TruthQos()),
        status(p, tp::kStatusTopic, tp::StatusQos()) {
    for (const RobotSpec& r : sc.robots) {
      odom.emplace(r.id, std::make_unique<tp::Writer<Odometry>>(p, tp::OdomTopic(r.id), tp::SensorQos()));
      scan.emplace(r.id, std::make_unique<tp::Writer<Scan>>(p, tp::ScanTopic(r.id), tp::SensorQos()));
    }
  }
  // Cumulative number of readers ever matched by both sensor writers of a robot.
  std::uint32_t TotalMatches(RobotId id) const {
    return std::min(odom.at(id)->raw().TotalMatchedReaders(), scan.at(id)->raw().TotalMatchedReaders());
  }
  std::map<RobotId, std::unique_ptr<tp::Writer<Odometry>>> odom;
  std::map<RobotId, std::unique_ptr<tp::Writer<Scan>>> scan;
  tp::Writer<RadioLinks> links;
  tp::Writer<GroundTruth> truth;
  tp::Reader<AgentStatus> status;
};

class Feeder {
 public:
  Feeder(const Scenario& sc, Channels& ch, AgentTracker& tracker, ControlInput& control,
         tp::ShutdownSignal& shutdown, bool events, double stall_timeout_s)
      : sc_(sc), ch_(ch), tracker_(tracker), control_(control), shutdown_(shutdown),
        events_(events), stall_timeout_s_(stall_timeout_s), keep_sent_(sc.feeder.pace == Pace::kLockstep) {
    for (const RobotSpec& r : sc.robots) matches_at_restart_[r.id] = 0;
  }

  // Reads statuses, liveliness changes, subscriptions, the processes of silent agents and
  // launcher commands.
  void Pump() {
    if (shutdown_.requested()) throw Interrupted();
    for (const auto& s : ch_.status.Take()) {
      const RobotId id = s.value.robot_id;
      if (s.valid) {
        spdlog::trace("status {} inc {} t {:.2f}", id, s.value.incarnation, s.value.processed_until);
        const bool was_silent = tracker_.IsSilent(id);
        tracker_.OnStatus(s.value);
        if (was_silent && !tracker_.IsSilent(id)) spdlog::info("agent {} speaks again", id);
        if (tracker_.IsUp(id) || tracker_.IsSilent(id)) sent_.Processed(id, s.value.processed_until);
      }
      if (!s.alive && !tracker_.IsDead(id) && !tracker_.IsSilent(id)) {
        // The writer of that status instance is gone (liveliness expired or it was disposed):
        // an invalid sample says so, or the state of a last sample still unread. While its
        // process exists the agent is only silent (paused, say): still waited for.
        const std::optional<int> pid = tracker_.process(id);
        const bool exists = pid && StateOf(*pid) != ProcessState::kGone;
        spdlog::warn("agent {} lost (DDS liveliness){}", id, exists ? "; its process exists: waiting for it" : "");
        tracker_.OnGone(id, exists);
      }
    }
    for (RobotId id : tracker_.Silent()) {
      const std::optional<int> pid = tracker_.process(id);
      if (!pid || StateOf(*pid) == ProcessState::kGone) {
        spdlog::warn("agent {}'s process is gone", id);
        tracker_.OnProcessGone(id);
        sent_.Forget(id);
      }
    }
    for (const auto& [id, base] : matches_at_restart_) {
      const std::uint32_t total = ch_.TotalMatches(id);
      const bool sub = total > base;
      if (sub != tracker_.IsSubscribed(id)) spdlog::debug("agent {} subscribed={}", id, sub);
      tracker_.SetSubscribed(id, sub);
      // Matched anew without a restart: the agent's participant lapsed (it was paused) and is
      // back. Whatever it had not processed may have been lost with the old match: send it again.
      std::uint32_t& last = last_matches_[id];
      if (total > last && last > base && !tracker_.IsDead(id)) Resend(id);
      last = total;
    }
    for (const ControlCommand& c : control_.Poll()) {
      switch (c.kind) {
        case ControlCommand::Kind::kDead:
          tracker_.MarkDead(c.id);
          sent_.Forget(c.id);
          spdlog::info("agent {} killed", c.id);
          break;
        case ControlCommand::Kind::kExpect:
          if (matches_at_restart_.count(c.id)) {
            matches_at_restart_[c.id] = ch_.TotalMatches(c.id);
            last_matches_[c.id] = matches_at_restart_[c.id];
          }
          tracker_.ExpectRestart(c.id);
          sent_.Forget(c.id);
          spdlog::info("agent {} restarting", c.id);
          break;
        case ControlCommand::Kind::kPid: tracker_.SetProcess(c.id, c.pid); break;
        case ControlCommand::Kind::kContinue: continue_ = true; break;
        case ControlCommand::Kind::kStop: throw Interrupted();
      }
    }
  }

  // Waits until no agent is starting; agents that do not come up in time count as failed.
  std::vector<RobotId> WaitForAgents(double timeout_s) {
    const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < deadline) {
      Pump();
      if (tracker_.Pending().empty()) return {};
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return tracker_.Pending();
  }

  // Lockstep barrier: waits until every up agent has processed what was published to it.
  void WaitForBarrier(const std::map<RobotId, double>& targets) {
    auto last_progress = Clock::now();
    double best = -1.0;
    while (true) {
      Pump();
      const auto lagging = tracker_.Lagging(targets);
      if (lagging.empty()) return;
      // Progress: the sum of what the lagging agents have processed grows.
      double sum = 0.0;
      for (const AgentStatus& s : tracker_.Statuses()) {
        if (std::find(lagging.begin(), lagging.end(), s.robot_id) != lagging.end()) sum += s.processed_until;
      }
      // A stopped (SIGSTOPped) agent is not stalled: it is waited for as long as it is stopped.
      const bool stopped = std::any_of(lagging.begin(), lagging.end(), [&](RobotId id) {
        const std::optional<int> pid = tracker_.process(id);
        return pid && StateOf(*pid) == ProcessState::kStopped;
      });
      if (sum > best || stopped) {
        best = std::max(best, sum);
        last_progress = Clock::now();
      } else if (Clock::now() - last_progress > std::chrono::duration<double>(stall_timeout_s_)) {
        for (RobotId id : lagging) {
          spdlog::error("agent {} made no progress for {:.0f} s; no longer waiting for it", id,
                        stall_timeout_s_);
          tracker_.MarkDead(id);
        }
        return;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  }

  // Stops at a hold point until the launcher says continue, then waits for restarted agents.
  void Hold(double stamp) {
    Emit({{"event", "hold"}, {"t", stamp}});
    continue_ = false;
    while (!continue_) {
      Pump();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    const auto failed = WaitForAgents(sc_.feeder.startup_timeout_s);
    for (RobotId id : failed) {
      spdlog::error("restarted agent {} did not come up within {:.0f} s", id, sc_.feeder.startup_timeout_s);
      tracker_.MarkDead(id);
    }
  }

  // Publishes a sensor message; in lockstep it is kept until the agent reports it processed.
  void Publish(const Odometry& o) {
    ch_.odom.at(o.robot_id)->Write(o);
    if (keep_sent_) sent_.Record(o);
  }
  void Publish(const Scan& s) {
    ch_.scan.at(s.robot_id)->Write(s);
    if (keep_sent_) sent_.Record(s);
  }
  // Sensor messages sent again to agents whose readers came back (see Pump).
  std::uint64_t resent() const { return resent_; }

  void Emit(const json& event) {
    if (!events_) return;
    std::fputs((event.dump() + "\n").c_str(), stdout);
    std::fflush(stdout);
  }

  json Progress(double stamp) const {
    std::uint64_t maps = 0;
    std::size_t aligned = 0;  // ordered pairs: agent A holds an alignment to B
    json alive = json::array();
    for (const AgentStatus& s : tracker_.Statuses()) {
      if (tracker_.IsUp(s.robot_id)) {
        alive.push_back(s.robot_id);
        maps += s.maps_received;
        aligned += s.peers_aligned.size();
      }
    }
    return {{"event", "progress"}, {"t", stamp}, {"duration", sc_.duration_s}, {"alive", alive},
            {"maps_received", maps}, {"aligned_pairs", aligned}};
  }

 private:
  const Scenario& sc_;
  Channels& ch_;
  AgentTracker& tracker_;
  ControlInput& control_;
  tp::ShutdownSignal& shutdown_;
  bool events_;
  double stall_timeout_s_;
  void Resend(RobotId id) {
    const std::vector<SentLog::Message> again = sent_.Unprocessed(id);
    if (again.empty()) return;
    spdlog::info("agent {} matched again: sending the {} sensor messages it has not processed", id, again.size());
    for (const SentLog::Message& m : again) {
      std::visit([&](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, Odometry>) {
          ch_.odom.at(id)->Write(x);
        } else {
          ch_.scan.at(id)->Write(x);
        }
      }, m);
    }
    resent_ += again.size();
  }

  bool continue_ = false;
  bool keep_sent_;
  SentLog sent_;
  std::uint64_t resent_ = 0;
  std::map<RobotId, std::uint32_t> matches_at_restart_;
  std::map<RobotId, std::uint32_t> last_matches_;
};

// What the feeder played: truth.json (the world and true trajectories) and feeder.json
// (what was published per robot, and for datasets what was read).
class PlayRecord {
 public:
  PlayRecord(const Scenario& sc, const FeedSource& source, std::vector<ReplayCounts> counts)
      : sc_(sc), counts_(std::move(counts)) {
    truth_.scenario = sc.name;
    truth_.duration_s = sc.duration_s;
    truth_.landmarks = source.Truth().landmarks;
    truth_.headings_known = source.Truth().headings_known;
    for (const RobotSpec& r : sc.robots) {
      io::RobotTruth rt;
      rt.id = r.id;
      for (const auto& [id, start] : source.Truth().starts) {
        if (id == r.id) rt.start = start;
      }
      truth_.robots.push_back(rt);
    }
  }
  void Add(const FeedBatch& b) {
    for (const GroundTruth& g : b.truth) {
      double& next = next_sample_[g.robot_id];
      if (g.stamp + 1e-9 < next) continue;
      for (auto& r : truth_.robots) {
        if (r.id == g.robot_id) r.trajectory.push_back({g.stamp, {g.x, g.y, g.theta}});
      }
      next = g.stamp + sc_.feeder.truth_period_s;
    }
  }
  void CountSent(const Scan& s) { ++scans_sent_[s.robot_id]; }
  void CountSent(const Odometry& o) { ++odom_sent_[o.robot_id]; }
  void Write(const std::string& dir, const FeedSource& source, double wall_s, bool interrupted,
             std::uint64_t resent = 0) {
    const auto& seen = source.Truth().seen;
    truth_.seen.clear();
    for (std::size_t i = 0; i < seen.size(); ++i) {
      if (seen[i]) truth_.seen.push_back(static_cast<int>(i));
    }
    io::WriteJsonAtomic(dir + "/truth.json", io::TruthToJson(truth_));
    json robots = json::array();
    for (const RobotSpec& r : sc_.robots) {
      json e = {{"id", r.id}, {"odom_sent", odom_sent_[r.id]}, {"scans_sent", scans_sent_[r.id]}};
      for (const ReplayCounts& c : counts_) {
        if (c.id != r.id) continue;
        e["odom_rows"] = c.odom_rows;
        e["odom_duplicate_rows"] = c.odom_duplicate_rows;
        e["measurement_rows"] = c.measurement_rows;
        e["measurement_unknown_barcode"] = c.measurement_unknown;
        e["robot_sightings"] = c.robot_sightings;
      }
      robots.push_back(e);
    }
    io::WriteJsonAtomic(dir + "/feeder.json", {{"scenario", sc_.name},
                                               {"source", std::string(NameOf(kSourceTypes, sc_.source.type))},
                                               {"sim_duration_s", sc_.duration_s},
                                               {"wall_s", wall_s},
                                               {"pace", std::string(NameOf(kPaces, sc_.feeder.pace))},
                                               {"interrupted", interrupted},
                                               {"sensor_messages_resent", resent},
                                               {"robots", robots}});
  }

 private:
  const Scenario& sc_;
  std::vector<ReplayCounts> counts_;
  io::RunTruth truth_;
  std::map<RobotId, double> next_sample_;
  std::map<RobotId, std::uint32_t> odom_sent_, scans_sent_;
};

int Run(int argc, char** argv) {
  tp::ShutdownSignal shutdown;  // first: block SIGINT/SIGTERM before any thread starts

  CLI::App cli{"mapmesh-feeder: simulates (or replays) the world and publishes it over DDS"};
  app::ProcessOptions po;
  std::string out_dir = ".", pace, datasets, record_path;
  double rate = 0.0, stall_timeout_s = 120.0;
  bool check_only = false, events = false, control_enabled = false, no_dds = false;
  std::vector<double> holds;
  app::AddScenarioOptions(cli, po);
  app::AddDdsOptions(cli, po, /*domain_required=*/false);
  cli.add_option("--out", out_dir, "directory for truth.json and feeder.json");
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
                               {"pace", std::string(NameOf(kPaces, sc.feeder.pace))}}
                               .dump()
                               .c_str());
    } else {
      std::printf("%s: ok: %zu robots, %zu landmarks, %.1f s\n", po.scenario_path.c_str(),
                  sc.robots.size(), source.Truth().landmarks.size(), sc.duration_s);
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
  std::filesystem::create_directories(out_dir);
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
    record.Write(out_dir, source, std::chrono::duration<double>(Clock::now() - wall_start).count(), false);
    return 0;
  }

  tp::Session session(po.domain, po.dds_config, app::DefaultDdsConfig());
  Channels ch(session.participant(), sc);
  AgentTracker tracker(ids);
  ControlInput control(control_enabled);
  shutdown.Watch(nullptr);
  Feeder feeder(sc, ch, tracker, control, shutdown, events, stall_timeout_s);
  const bool lockstep = sc.feeder.pace == Pace::kLockstep;
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
    std::sort(holds.begin(), holds.end());
    std::deque<double> hold_queue(holds.begin(), holds.end());
    const double window = sc.feeder.lockstep_window_s;
    double next_barrier = window;
    auto last_progress = Clock::now() - std::chrono::seconds(10);
    const auto play_start = Clock::now();
    // Lockstep holds back each robot's latest odometry until it is known whether a barrier
    // comes before that robot's next one: the held message then carries the sync flag, and
    // the barrier waits for exactly the stamps published per robot.
    std::map<RobotId, Odometry> held;
    std::map<RobotId, double> published_until;
    auto publish_odom = [&](const Odometry& o) {
      feeder.Publish(o);
      record.CountSent(o);
      published_until[o.robot_id] = o.stamp;
    };
    while (!source.Done()) {
      const FeedBatch b = source.Next();
      if (recording) recording->Write(b);
      record.Add(b);
      const bool last = source.Done();
      const bool barrier = b.stamp + 1e-9 >= next_barrier || last ||
                           (!hold_queue.empty() && b.stamp + 1e-9 >= hold_queue.front());
      if (!lockstep) {
        const auto due = play_start + std::chrono::duration_cast<Clock::duration>(
                                          std::chrono::duration<double>(b.stamp / sc.feeder.realtime_factor));
        while (Clock::now() < due) {
          feeder.Pump();
          std::this_thread::sleep_until(std::min(due, Clock::now() + std::chrono::milliseconds(20)));
        }
      }
      if (b.links) ch.links.Write(*b.links);
      for (const Scan& s : b.scans) {
        feeder.Publish(s);
        record.CountSent(s);
      }
      for (const GroundTruth& g : b.truth) ch.truth.Write(g);
      for (const Odometry& o : b.odom) {
        if (!lockstep) {
          publish_odom(o);
          continue;
        }
        if (auto it = held.find(o.robot_id); it != held.end()) publish_odom(it->second);
        held[o.robot_id] = o;
      }
      if (!barrier) continue;
      for (auto& [id, o] : held) {
        o.sync = true;
        publish_odom(o);
      }
      held.clear();
      if (lockstep) feeder.WaitForBarrier(published_until);
      feeder.Pump();
      while (next_barrier <= b.stamp + 1e-9) next_barrier += window;
      if (Clock::now() - last_progress > std::chrono::milliseconds(500) || last) {
        feeder.Emit(feeder.Progress(b.stamp));
        last_progress = Clock::now();
      }
      while (!hold_queue.empty() && b.stamp + 1e-9 >= hold_queue.front()) {
        hold_queue.pop_front();
        if (control.enabled()) feeder.Hold(b.stamp);
      }
    }
  } catch (const Interrupted&) {
    spdlog::warn("interrupted: writing what was played so far");
    exit_code = kExitInterrupted;
  }

  // Let the agents that are up acknowledge the tail of their streams before the writers go
  // away (a killed agent's reader stays matched until its lease ends; do not wait for it).
  for (RobotId id : tracker.Up()) {
    ch.odom.at(id)->raw().WaitForAcks(2.0);
    ch.scan.at(id)->raw().WaitForAcks(2.0);
  }
  if (recording) recording->Close();
  const double wall_s = std::chrono::duration<double>(Clock::now() - wall_start).count();
  record.Write(out_dir, source, wall_s, exit_code != 0, feeder.resent());
  feeder.Emit({{"event", "done"}, {"wall_s", wall_s}, {"interrupted", exit_code != 0}});
  spdlog::info("done in {:.1f} s wall", wall_s);
  return exit_code;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-feeder", [&] { return mapmesh::Run(argc, argv); });
}
