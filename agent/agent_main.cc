// mapmesh-agent: one robot's process. It wires AgentNode to DDS: sensor streams in, maps
// and status out, peers' maps in through the radio gate; on SIGTERM/SIGINT/SIGHUP it writes its
// final maps and statistics and exits 0.

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <deque>
#include <filesystem>
#include <map>
#include <optional>
#include <utility>

#include "agent/agent_node.h"
#include "agent/agent_setup.h"
#include "common/app/process.h"
#include "common/io/checkpoint.h"
#include "common/io/run_files.h"
#include "common/map/wire_bytes.h"
#include "common/transport/oversize_counter.h"
#include "common/transport/session.h"
#include "common/transport/shutdown.h"
#include "common/transport/submap_signer.h"
#include "common/transport/topics.h"
#include "common/transport/typed.h"

namespace mapmesh {

// stats.json: each struct's counters under their own names.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(SyncStats, odom_received, odom_processed, odom_rejected, odom_implausible,
                                   odometry_lost, odom_duplicate, odom_out_of_sequence, odom_before_join,
                                   scans_received, scans_implausible, scans_lost, scans_duplicate,
                                   scans_out_of_sequence, scans_before_join, scans_processed, scans_empty,
                                   scans_rejected, scans_before_start, scans_late, scans_missing)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(MapperStats, offered, associated, initialised, tentative, rejected_gate, ambiguous,
                                   unidentified, out_of_range, invalid, failed_updates, diverged)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(AgentStats, maps_sent, bytes_sent, maps_received, bytes_received, maps_out_of_range,
                                   maps_lost, maps_over_bandwidth, maps_delayed, maps_delay_overflow, in_flight,
                                   maps_unknown_sender, maps_stale_version, maps_encode_failed, maps_encode_trimmed,
                                   maps_beyond_sample_size, links_refused)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(PeerReport, own_checkpoint, origin_stamp, local_landmarks, global_landmarks, aligned,
                                   ever_aligned, aligned_since, dropped, stale, stale_since, frozen, silent, last_heard,
                                   relayed, relay_conflicts, refuted, refuted_by, replaced, superseded, refuted_answers,
                                   attempts, unconfirmed, outsupported, verifications, failures, rejected, drops,
                                   realignments, refinements, corrections, rendezvous_fits, rendezvous_refused,
                                   rendezvous_unjudged, rendezvous_confirmed)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(RendezvousStats, sightings_sent, answers_sent, sightings_used, answers_used, mutual,
                                   refused, unmatched, fits, fits_accepted)

namespace {

namespace tp = transport;
using io::json;

// Sends the agent's messages through DDS writers. The status is best-effort, and the feeder's
// lockstep barrier waits for it: each status the node publishes is sent once more a moment
// later (with what the node then knows), so that one lost datagram on a lossy link does not
// hold the barrier until the next beat.
class DdsOutput : public AgentOutput {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr auto kStatusRepeat = std::chrono::milliseconds(30);

  DdsOutput(const tp::Participant& p, double lease_s, RobotId self, bool lockstep)
      : maps_(p, tp::kMapTopic, tp::MapQosFor(lockstep, lease_s).Partition(tp::RobotPartition(self))),
        status_(p, tp::kStatusTopic, tp::StatusQos(lease_s).Partition(tp::RobotPartition(self))) {
    // In lockstep sightings ride on the tick's local map: no sighting topic.
    if (!lockstep) sightings_.emplace(p, tp::kSightingTopic, tp::SightingQos().Partition(tp::RobotPartition(self)));
  }
  void PublishMap(const MapMessage& msg) override { maps_.Write(msg); }
  void PublishStatus(const AgentStatus& status) override {
    status_.Write(status);
    repeat_at_ = Clock::now() + kStatusRepeat;
  }
  void PublishSighting(const Sighting& s) override {
    if (sightings_) sightings_->Write(s);
  }
  // A status sent on the launcher's beat or as a repeat: no repeat of its own.
  void SendStatus(const AgentStatus& status) { status_.Write(status); }
  // When the last status published by the node is due to be repeated (nullopt: none is).
  std::optional<Clock::time_point> RepeatDue() const { return repeat_at_; }
  void RepeatDone() { repeat_at_.reset(); }

 private:
  std::optional<Clock::time_point> repeat_at_;
  tp::Writer<MapMessage> maps_;
  tp::Writer<AgentStatus> status_;
  std::optional<tp::Writer<Sighting>> sightings_;
};

// A map keyed by robot as a JSON object (keys are strings).
template <typename T>
json ByRobot(const std::map<RobotId, T>& m) {
  json out = json::object();
  for (const auto& [id, v] : m) out[std::to_string(id)] = v;
  return out;
}

json PeersJson(const AgentNode& node, const std::map<RobotId, double>& lost_wall) {
  json peers = json::array();
  for (const PeerReport& p : node.exchange().Peers()) {
    const Eigen::Matrix3d& c = p.to_own_cov;
    json j = p;
    j.update({{"robot", p.key.robot},
              {"incarnation", p.key.incarnation},
              {"transform", {p.to_own.x, p.to_own.y, p.to_own.theta}},
              {"transform_cov", {c(0, 0), c(0, 1), c(0, 2), c(1, 1), c(1, 2), c(2, 2)}},
              {"centroid", {p.centroid.x(), p.centroid.y()}},
              {"last_verdict", std::string(ToString(p.last_verdict))},
              {"aligned_by", ToString(p.aligned_by)},
              {"first_aligned_by", ToString(p.first_aligned_by)}});
    peers.push_back(std::move(j));
  }
  return {{"peers", peers}, {"peers_lost_wall", ByRobot(lost_wall)}};
}

// One log line per alignment event (aligned, corrected, refuted, dropped), so that the log
// tells how the global map came to be. Alignments change only when the agent publishes its
// maps (MapExchange::Update): the peers are compared only then, not at every wake-up.
void LogPeerEvents(const AgentNode& node, std::map<PeerKey, PeerReport>& last, std::uint64_t& updates) {
  if (node.exchange().updates() == updates) return;
  updates = node.exchange().updates();
  for (const PeerReport& p : node.exchange().Peers()) {
    const PeerReport before = std::exchange(last.try_emplace(p.key).first->second, p);
    const double t = node.processed_until();
    const auto who = [&] {
      return fmt::format("peer {}.{}{}", p.key.robot, p.key.incarnation, p.own_checkpoint ? " (own checkpoint)" : "");
    };
    if (p.replaced > before.replaced) {
      spdlog::info("t={:.1f}s {}: frozen; re-placed where peer {}'s relay puts its landmarks", t, who(), p.refuted_by);
    } else if (p.refuted > before.refuted) {
      spdlog::info("t={:.1f}s {}: our alignment refuted by peer {}'s relay; dropped", t, who(), p.refuted_by);
    } else if (p.drops > before.drops) {
      spdlog::info("t={:.1f}s {}: alignment dropped after {} failed verifications", t, who(), before.failures + 1);
    }
    if (p.aligned && (!before.aligned || p.corrections > before.corrections)) {
      spdlog::info("t={:.1f}s {}: {} at ({:.2f} m, {:.2f} m, {:.2f} deg){}", t, who(),
                   before.aligned ? "realigned" : "aligned", p.to_own.x, p.to_own.y, RadToDeg(p.to_own.theta),
                   p.relayed ? ", relaying its global map" : "");
    }
  }
}

// A warning line when the agent refuses input or cannot send its map (what and how many since
// the last line), at most one every 5 wall seconds: a flood of bad input must not flood the log.
// The counts are looked at once a wall second.
class InputWatch {
 public:
  void Check(const AgentNode& node) {
    const auto now = std::chrono::steady_clock::now();
    if (now < next_) return;
    const AgentStats& s = node.stats();
    const SyncStats y = node.sync_stats();
    const std::map<std::string, std::uint64_t> counts = {
        {"peer maps refused", s.MapsRefused()},
        {"peer maps malformed", s.MapsRejected()},
        {"link tables refused", s.links_refused},
        {"odometry implausible", y.odom_implausible},
        {"scans implausible", y.scans_implausible},
        {"odometry lost", y.odometry_lost},
        {"scans lost", y.scans_lost},
        {"odometry out of sequence", y.odom_out_of_sequence},
        {"scans out of sequence", y.scans_out_of_sequence},
        {"own maps not encodable", s.maps_encode_failed},
        {"own maps beyond the sample size", s.maps_beyond_sample_size}};
    std::string what;
    for (const auto& [name, n] : counts) {
      const std::uint64_t before = last_.count(name) ? last_[name] : 0;
      if (n > before) what += fmt::format("{}{} {}", what.empty() ? "" : ", ", n - before, name);
      last_[name] = n;
    }
    if (what.empty()) {
      next_ = now + std::chrono::seconds(1);  // looked at once a second, not at every wake-up
      return;
    }
    if (s.maps_encode_failed > 0) what += fmt::format(" (last encoding error: {})", ToString(s.last_encode_error));
    spdlog::warn("t={:.1f}s input refused or lost: {}", node.processed_until(), what);
    next_ = now + std::chrono::seconds(5);
  }

 private:
  std::map<std::string, std::uint64_t> last_;
  std::chrono::steady_clock::time_point next_{};
};

// Samples refused because their robot id was not their writer's partition's (topics.h):
// someone publishing as another robot. By topic, then by the robot claimed.
// Link tables and ticks not from the run's feeder (FeederSource), by topic.
struct SenderRefusals {
  std::map<RobotId, std::uint64_t> maps, sightings;
  const tp::OversizeCounter* oversize = nullptr;  // samples the transport dropped for their size
  std::size_t max_sample_bytes = 0;               // ... beyond this (AgentNode::MaxSampleBytes)
  bool warned = false;
  tp::FeederSource links, ticks;
  bool feeder_warned = false;
};

// Whether the agent can still write its outputs. The first failed write (a full disk, an I/O
// error) stops its snapshots and checkpoints for the rest of the incarnation, counted and
// logged once; mapping and the exchange go on, and the final outputs are tried once more.
struct OutputHealth {
  std::uint64_t write_failures = 0;
  std::optional<double> stopped_at;  // processed_until at the first failure
  std::string reason;                // that failure's "PATH: REASON"
  void Failed(const io::WriteError& e, double t) {
    ++write_failures;
    if (stopped_at) return;
    stopped_at = t;
    reason = e.what();
    spdlog::error("{}: snapshots and checkpoints stop here (t={:.1f}s); mapping goes on (stats.json outputs)", reason,
                  t);
  }
};

json StatsJson(const AgentNode& node, const std::map<RobotId, double>& lost_wall, const SenderRefusals& refusals,
               const OutputHealth& health) {
  const AgentStats& s = node.stats();
  json rejected = json::object();
  for (int i = 1; i < kMapDecodeErrorCount; ++i) {
    rejected[std::string(ToString(static_cast<MapDecodeError>(i)))] = s.maps_rejected[i];
  }
  json refused = json::object();
  for (int i = 0; i < kMapRefusalCount; ++i)
    refused[std::string(ToString(static_cast<MapRefusal>(i)))] = s.maps_refused[i];
  json submap_rejected = json::object();
  for (int i = 1; i < kSubmapDecodeErrorCount; ++i) {
    submap_rejected[std::string(ToString(static_cast<SubmapDecodeError>(i)))] = s.submaps_rejected[i];
  }
  json submap_refused = json::object();
  for (int i = 0; i < kSubmapRefusalCount; ++i) {
    submap_refused[std::string(ToString(static_cast<SubmapRefusal>(i)))] = s.submaps_refused[i];
  }
  // Lockstep: the peers' messages the inbox refused, by reason (lockstep_inbox.h).
  json inbox_refused = json::object();
  for (int i = 0; i < kInboxRefusalCount; ++i) {
    inbox_refused[std::string(ToString(static_cast<InboxRefusal>(i)))] = node.inbox_refused()[static_cast<std::size_t>(
        i)];
  }
  const SubmapRelay::Counters& sc = node.submaps().counters();
  // Each chain held: how many from index 0 without a gap, how many in all, and the digest of
  // each of the first (FNV-1a of its bytes): two agents holding a submap hold the same bytes.
  json chains = json::array();
  const SubmapBook& book = node.submaps().book();
  for (const SubmapChain& c : book.Chains()) {
    json digests = json::array();
    for (std::uint32_t i = 0; i < c.count; ++i) {
      digests.push_back(fmt::format("{:016x}", wire::Fnv1a64(*book.Bytes({c.robot, c.incarnation, i}))));
    }
    std::size_t held = 0;
    double closed_until = 0.0;  // the latest closing of a submap held: the robot's data that reached us in submaps
    for (const SubmapId& id : book.Ids()) {
      if (id.robot != c.robot || id.incarnation != c.incarnation) continue;
      ++held;
      closed_until = std::max(closed_until, book.Find(id)->closed_s);
    }
    chains.push_back({{"robot", c.robot},
                      {"incarnation", c.incarnation},
                      {"count", c.count},
                      {"held", held},
                      {"closed_until", closed_until},
                      {"digests", digests}});
  }
  const Pose2 pose = node.Pose();
  const AgentStatus status = node.Status();
  json j = s;
  j.update(node.sync_stats());
  j.update({{"id", node.id()},
            {"incarnation", node.incarnation()},
            {"processed_until", node.processed_until()},
            {"frame_origin_stamp", node.frame_origin_stamp() ? json(*node.frame_origin_stamp()) : json()},
            {"pose", {pose.x, pose.y, pose.theta}},
            {"local_landmarks", node.LocalMap().size()},
            {"global_landmarks", node.global().map.size()},
            {"observations", node.mapper().stats()},
            {"bytes_per_landmark", s.BytesPerLandmark()},
            {"payload_bytes_sent", s.payload_bytes_sent},  // of bytes_sent: the maps' payloads
            {"landmarks_sent", s.landmarks_sent},
            {"maps_dropped", s.MapsDropped()},
            {"maps_rejected", rejected},
            {"maps_refused", refused},
            {"inbox_refused", inbox_refused},
            {"maps_received_from", ByRobot(s.maps_received_from)},
            {"data_until", ByRobot(s.data_until)},
            {"peers_aligned", status.peers_aligned},
            {"peers_stale", status.peers_stale},
            {"sightings",
             {{"sent", s.sightings_sent},
              {"unsent", s.sightings_unsent},
              {"bytes_sent", s.sighting_bytes_sent},
              {"received", s.sightings_received},
              {"gated", s.sightings_gated},
              {"implausible", s.sightings_implausible},
              {"delayed", s.sightings_delayed},
              {"tracker", node.rendezvous_stats()}}},
            {"submaps",
             {{"own", sc.own},
              {"unsendable", s.submaps_unsendable},
              {"held", node.submaps().book().size()},
              {"held_bytes", node.submaps().book().bytes()},
              {"chains", chains},
              {"received_new", sc.received_new},
              {"restored", sc.restored},
              {"duplicates", sc.duplicates},
              {"conflicts", sc.conflicts},
              {"owner_conflicts", sc.owner_conflicts},
              {"ahead_of_owner", sc.ahead_of_owner},
              {"full", sc.full},
              {"chain_full", sc.chain_full},
              {"sent", sc.sent},
              {"bytes_sent", sc.bytes_sent},
              {"sent_again", sc.sent_again},
              {"held_back", sc.held_back},
              {"debt_paid", sc.debt_paid},
              {"open_own_bytes_sent", s.open_submap_bytes_sent},
              {"open_held", node.submaps().open().size()},
              {"open_taken", sc.open_taken},
              {"open_gaps", sc.open_gaps},
              {"open_relayed", sc.open_relayed},
              {"open_bytes_relayed", sc.open_bytes_relayed},
              {"rejected", submap_rejected},
              {"refused", submap_refused}}},
            {"joining",
             {{"solves", node.exchange().joining().solves},
              {"chains_held", node.exchange().joining().chains_held},
              {"chains", node.exchange().joining().chains},
              {"chains_joined", node.exchange().joining().chains_joined},
              {"sources_by_ci", node.exchange().joining().sources_by_ci},
              {"submaps", node.exchange().joining().submaps},
              {"submaps_summarised", node.exchange().joining().submaps_summarised},
              {"calibrated_solves", node.exchange().joining().calibrated_solves},
              {"chains_calibrated", node.exchange().joining().chains_calibrated},
              {"worst_variance_factor", node.exchange().joining().worst_variance_factor},
              {"iterations", node.exchange().joining().iterations},
              {"converged", node.exchange().joining().converged},
              {"solved", node.exchange().joining().solved},
              {"ties", node.exchange().joining().ties},
              {"ties_dropped", node.exchange().joining().ties_dropped},
              {"first_passes", node.exchange().joining().first_passes},
              {"placed_alone", node.exchange().joining().placed_alone},
              {"rechecks", node.exchange().joining().rechecks},
              {"rechecks_unchanged", node.exchange().joining().rechecks_unchanged},
              {"rechecks_spared", node.exchange().joining().rechecks_spared},
              {"relayed_chains", node.exchange().joining().relayed_chains},
              {"relayed_placed", node.exchange().joining().relayed_placed},
              {"relayed_alignments", node.exchange().joining().relayed_alignments},
              {"relayed_disagreements", node.exchange().joining().relayed_disagreements},
              {"relayed_by_placement", node.exchange().joining().relayed_by_placement},
              {"placements_refused", node.exchange().joining().placements_refused},
              {"superseded_chains", node.exchange().joining().superseded_chains},
              {"chains_extended", node.exchange().joining().chains_extended}}},
            {"ci_piecewise",
             {{"submaps", node.exchange().piecewise().submaps},
              {"fitted", node.exchange().piecewise().fitted},
              {"refused", node.exchange().piecewise().refused},
              {"chained", node.exchange().piecewise().chained},
              {"pairs", node.exchange().piecewise().pairs},
              {"rest", node.exchange().piecewise().rest}}},
            {"impersonations_refused", {{"maps", ByRobot(refusals.maps)}, {"sightings", ByRobot(refusals.sightings)}}},
            {"not_from_feeder", {{"links", refusals.links.refused()}, {"ticks", refusals.ticks.refused()}}},
            {"transport_oversize",
             {{"dropped", refusals.oversize ? refusals.oversize->received() : 0},
              {"max_sample_bytes", refusals.max_sample_bytes}}},
            {"outputs",
             {{"write_failures", health.write_failures},
              {"stopped_at", health.stopped_at ? json(*health.stopped_at) : json()},
              {"reason", health.reason}}}});
  j.update(PeersJson(node, lost_wall));
  return j;
}

// The agent's maps, statistics and trajectory. Written at every checkpoint too (final false),
// so that an agent killed without warning leaves its last state behind.
// Throws io::WriteError.
void CreateDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) throw io::WriteError(path, ec.value());
}

void WriteOutputs(const AgentNode& node, const std::string& dir, const std::map<RobotId, double>& lost_wall,
                  const SenderRefusals& refusals, const OutputHealth& health, bool final) {
  CreateDirectories(dir + "/snapshots");
  const json local = io::MapToJson(node.LocalMap());
  const json global = io::GlobalMapToJson(node.global());
  io::WriteJsonAtomic(dir + "/local_map.json", local);
  io::WriteJsonAtomic(dir + "/global_map.json", global);
  json stats = StatsJson(node, lost_wall, refusals, health);
  stats["final"] = final;
  io::WriteJsonAtomic(dir + "/stats.json", stats);
  // The history of the run for plots over time: both maps as they were now, and one line of
  // counters in history.jsonl (appended; a resumed agent continues it with its incarnation).
  const std::string snapshot = fmt::format("snapshots/t{:010.3f}_i{}", node.processed_until(), node.incarnation());
  io::WriteJsonAtomic(dir + "/" + snapshot + "_local.json", local);
  io::WriteJsonAtomic(dir + "/" + snapshot + "_global.json", global);
  json line = {{"t", node.processed_until()}, {"snapshot", snapshot}, {"final", final}};
  for (const char* key : {"incarnation", "frame_origin_stamp", "local_landmarks", "global_landmarks", "bytes_sent",
                          "bytes_received", "maps_received", "maps_received_from", "peers_aligned", "peers_stale"}) {
    line[key] = stats.at(key);
  }
  io::AppendLine(dir + "/history.jsonl", line.dump());
  if (final) {
    // The last maps received from each peer, in the peer's frame: what a dead peer left us.
    CreateDirectories(dir + "/peers");
    for (const MapExchange::Received& r : node.exchange().ReceivedMaps()) {
      const std::string base = fmt::format("{}/peers/{}_{}", dir, r.key.robot, r.key.incarnation);
      if (r.local) io::WriteJsonAtomic(base + "_local.json", io::MapToJson(*r.local));
      if (r.global) io::WriteJsonAtomic(base + "_global.json", io::MapToJson(*r.global));
    }
  }
  io::WriteJsonAtomic(dir + "/trajectory.json", io::TrajectoryToJson(node.trajectory(), node.frame_origin_stamp()));
}

double WallNow() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

int Run(int argc, char** argv) {
  tp::ShutdownSignal shutdown;  // first: block SIGINT/SIGTERM/SIGHUP before any thread starts

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
  bool resume = false;
  cli.add_flag(
      "--resume", resume,
      "restart from OUT/checkpoint.json: re-merge what the earlier incarnation knew (it starts a new map frame)");
  std::string peer_certificates;
  cli.add_option("--peer-certificates", peer_certificates,
                 "secure runs: the directory of every robot's certificate, agent<id>.pem, which its submaps' "
                 "signatures are checked with (default: the directory of this agent's own certificate)");
  if (auto code = app::ParseArgs(cli, "mapmesh-agent", argc, argv)) return *code;
  app::SetupLogging("agent " + std::to_string(id), po.log_level);
  if (out_dir.empty()) out_dir = "agent_" + std::to_string(id);

  const std::optional<Scenario> loaded = app::LoadScenarioOrReport("mapmesh-agent", po);
  if (!loaded) return 2;
  const Scenario& scenario = *loaded;
  if (!scenario.FindRobot(static_cast<RobotId>(id))) {
    std::fprintf(stderr, "mapmesh-agent: %s: robots: no robot with id %d in this run\n", po.scenario_path.c_str(), id);
    return 2;
  }

  // The checkpoint is validated before any DDS entity exists: a bad one ends the process at
  // once with one line, and a missing one is a fresh start.
  const RobotId self = static_cast<RobotId>(id);
  const std::string checkpoint_path = out_dir + "/checkpoint.json";
  std::optional<AgentCheckpoint> checkpoint;
  if (resume) {
    // Within the bounds a peer's map must keep: the world's extent, and the run's end (as sensor stamps).
    io::CheckpointLimits limits;
    limits.max_abs_coordinate_m = scenario.agent.peer_limits.world_radius_m;
    limits.max_stamp_s = AgentRunFor(scenario, self).end_s + scenario.agent.max_stamp_jump_s;
    limits.submap_limits = scenario.agent.peer_limits;
    io::CheckpointLoad loaded_checkpoint = io::LoadCheckpoint(checkpoint_path, self, incarnation, limits);
    if (loaded_checkpoint.missing) {
      spdlog::warn("--resume: no checkpoint at {}; starting afresh", checkpoint_path);
    } else if (!loaded_checkpoint.ok()) {
      std::fprintf(stderr, "mapmesh-agent: %s\n", loaded_checkpoint.error.c_str());
      return 2;
    }
    checkpoint = std::move(loaded_checkpoint.checkpoint);
  }

  const AgentRun run = AgentRunFor(scenario, self);
  // A sample longer than any the run's agents send is dropped by the transport before it costs
  // memory (issue R3: a hostile 4 MB map took 23 MB of an agent's 16 MB before the inbox refused it).
  const std::size_t max_sample_bytes = AgentNode::MaxSampleBytes(scenario.agent, run);
  const tp::OversizeCounter oversize;  // before the session: Cyclone's drops counted from the start
  tp::Session session(po.domain, po.dds_config, app::DefaultDdsConfig(), max_sample_bytes);
  spdlog::info("samples beyond {} bytes dropped by the transport (Cyclone MaxSampleSize)", max_sample_bytes);
  const tp::Participant& p = session.participant();
  tp::Reader<Odometry> odom(p, tp::OdomTopic(self), tp::SensorQos());
  tp::Reader<Scan> scans(p, tp::ScanTopic(self), tp::SensorQos());
  tp::Reader<RadioLinks> links(p, tp::kLinksTopic, tp::FeederTopicReader(tp::LinksQos()));
  const double lease_s = scenario.agent.LivelinessLeaseS(scenario.robots.size());
  // In lockstep the maps are exchanged at the feeder's ticks (messages.h ExchangeTick),
  // reliably, and sightings ride on them; in real time maps and sightings go out as the agent
  // goes, on topics of their own.
  const bool lockstep = run.exchange_ticks;
  tp::Reader<MapMessage> maps(
      p, tp::kMapTopic,
      (lockstep ? tp::LockstepMapQos(lease_s) : tp::MapQos(lease_s)).Partition(tp::kEveryRobotPartition));
  std::optional<tp::Reader<Sighting>> sightings;
  if (!lockstep) sightings.emplace(p, tp::kSightingTopic, tp::SightingQos().Partition(tp::kEveryRobotPartition));
  tp::Reader<ExchangeTick> ticks(p, tp::kTickTopic, tp::FeederTopicReader(tp::TickQos()));
  tp::WriterPartitions map_writers(maps.raw()), links_writers(links.raw()), tick_writers(ticks.raw());
  std::optional<tp::WriterPartitions> sighting_writers;
  if (sightings) sighting_writers.emplace(sightings->raw());
  DdsOutput output(p, lease_s, self, lockstep);
  AgentNode node(scenario.agent, run, self, incarnation, output);
  // Secure runs: submaps signed by their robot and checked at every receiver (issue R3).
  std::unique_ptr<tp::SubmapSigner> signer;
  if (session.security()) {
    std::string why;
    signer = tp::SubmapSigner::Make(*session.security(), self, peer_certificates, &why);
    if (!signer) {
      std::fprintf(stderr, "mapmesh-agent: %s\n", why.c_str());
      return 2;
    }
    for (RobotId r : run.robots) {
      if (r == self) continue;
      if (const std::optional<std::string> problem = signer->PeerProblem(r))
        spdlog::warn("robot {}'s submaps will be refused (unknown_signer): {}", r, *problem);
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
  std::map<RobotId, double> lost_wall;  // when each peer's liveliness was lost (wall clock, for tests)

  tp::GuardCondition stop(p);
  tp::WaitSet waitset(p);
  waitset.AttachReader(odom.raw(), 1);
  waitset.AttachReader(scans.raw(), 2);
  waitset.AttachReader(links.raw(), 3);
  waitset.AttachReader(maps.raw(), 4);
  if (sightings) waitset.AttachReader(sightings->raw(), 6);
  waitset.AttachReader(ticks.raw(), 7);
  waitset.AttachGuard(stop, 5);
  shutdown.Watch(&stop);
  spdlog::info("up: scenario {} domain {} config {} incarnation {} liveliness lease {} s", scenario.name, po.domain,
               session.config_used(), incarnation, lease_s);

  // Status also goes out on a wall-clock beat: the feeder learns we exist before any data,
  // and a lost best-effort status never stalls lockstep for long.
  using Clock = std::chrono::steady_clock;
  constexpr auto kStatusBeat = std::chrono::milliseconds(200);
  output.SendStatus(node.Status());
  auto next_beat = Clock::now() + kStatusBeat;
  std::map<PeerKey, PeerReport> peer_events;
  std::uint64_t peer_events_at = 0;  // the exchange's update they were taken at
  InputWatch input_watch;
  SenderRefusals refusals;
  refusals.oversize = &oversize;
  refusals.max_sample_bytes = max_sample_bytes;
  OutputHealth health;
  auto speaks_for = [&](tp::WriterPartitions& writers, dds_instance_handle_t publication, RobotId robot,
                        std::map<RobotId, std::uint64_t>& refused) {
    if (tp::SpeaksFor(writers.Of(publication), robot)) return true;
    ++refused[robot];
    if (!refusals.warned) {
      spdlog::warn("refused a sample claiming robot {} from a writer outside partition {} (counted in stats.json "
                   "impersonations_refused)",
                   robot, tp::RobotPartition(robot));
      refusals.warned = true;
    }
    return false;
  };
  auto from_feeder = [&](tp::FeederSource& source, tp::WriterPartitions& writers, dds_instance_handle_t publication,
                         const char* what) {
    const tp::FeederSource::Verdict v = source.Judge(writers.Of(publication), writers.GuidOf(publication));
    if (v == tp::FeederSource::Verdict::kFeeder) return true;
    if (!refusals.feeder_warned) {
      spdlog::warn("refused {} from {} (counted in stats.json not_from_feeder)", what,
                   v == tp::FeederSource::Verdict::kSecondWriter ? "a second writer in the feeder's partition"
                                                                 : "a writer outside the feeder's partition");
      refusals.feeder_warned = true;
    }
    return false;
  };
  // Exchange ticks not carried out yet (they wait for their link table or a peer's message),
  // in the order they came.
  std::deque<ExchangeTick> pending_ticks;
  std::optional<std::chrono::steady_clock::time_point> tick_waiting_since;
  // Everything the readers hold, into the node.
  auto pump = [&] {
    for (const auto& s : links.Take()) {
      if (s.valid && from_feeder(refusals.links, links_writers, s.publication, "a link table")) node.OnLinks(s.value);
    }
    for (const auto& s : scans.Take()) {
      if (s.valid) node.OnScan(s.value);
    }
    for (const auto& s : odom.Take()) {
      if (s.valid) node.OnOdometry(s.value);
    }
    if (sightings) {
      for (const auto& s : sightings->Take()) {
        if (s.valid && speaks_for(*sighting_writers, s.publication, s.value.robot_id, refusals.sightings))
          node.OnSighting(s.value);
      }
    }
    for (const auto& s : maps.Take()) {
      if (s.valid && speaks_for(map_writers, s.publication, s.value.robot_id, refusals.maps)) {
        const std::string* guid = map_writers.GuidOf(s.publication);  // known: speaks_for found the writer
        node.OnMap(s.value, guid ? *guid : std::string());
      }
      // A peer's writer is gone: an invalid sample carries that, or the state of its last
      // sample when that was still unread.
      if (!s.alive && node.OnPeerLiveliness(s.value.robot_id, false)) {
        if (!lost_wall.count(s.value.robot_id)) {
          spdlog::info("peer {} lost (liveliness)", s.value.robot_id);
          lost_wall[s.value.robot_id] = WallNow();
        }
      }
    }
    for (const auto& s : ticks.Take()) {
      if (s.valid && from_feeder(refusals.ticks, tick_writers, s.publication, "an exchange tick"))
        pending_ticks.push_back(s.value);
    }
    while (!pending_ticks.empty() && node.OnTick(pending_ticks.front())) {
      pending_ticks.pop_front();
      tick_waiting_since.reset();
    }
    if (pending_ticks.empty()) return;
    // A tick that waits long: say what for (a message that never comes holds the whole run).
    const auto now = Clock::now();
    if (!tick_waiting_since) tick_waiting_since = now;
    if (now - *tick_waiting_since > std::chrono::seconds(5)) {
      const ExchangeTick& t = pending_ticks.front();
      std::string what;
      for (const TickPeer& m : node.Missing(t))
        what += fmt::format(" {}.{} ({} here)", m.robot, m.incarnation, m.messages);
      spdlog::warn("exchange tick {} ({}) waits: messages missing from{}", t.index,
                   t.phase == TickPhase::kExchange ? "exchange" : "deliver", what.empty() ? " none" : what);
      tick_waiting_since = now;
    }
  };
  bool warned_left_out = false, warned_submaps_left_out = false;
  const auto save_checkpoint = [&] {
    std::size_t left_out = 0, submaps_left_out = 0;
    io::WriteJsonAtomic(checkpoint_path, io::CheckpointToJson(node.Checkpoint(&left_out, &submaps_left_out)));
    if (left_out > 0 && !warned_left_out) {
      spdlog::warn(
          "checkpoint: {} oldest earlier incarnations never re-merged are left out (a checkpoint holds {} at most)",
          left_out, io::CheckpointLimits{}.max_earlier);
      warned_left_out = true;
    }
    if (submaps_left_out > 0 && !warned_submaps_left_out) {
      spdlog::warn("checkpoint: {} of the submaps held are left out (a checkpoint holds {} at most, {} MiB)",
                   submaps_left_out, io::CheckpointLimits{}.max_submaps, io::CheckpointLimits{}.max_submap_bytes >> 20);
      warned_submaps_left_out = true;
    }
  };
  while (!shutdown.requested()) {
    double wait_s = 0.1;
    if (const auto due = output.RepeatDue()) {
      wait_s = std::clamp(std::chrono::duration<double>(*due - Clock::now()).count(), 0.0, wait_s);
    }
    waitset.Wait(wait_s);
    pump();
    LogPeerEvents(node, peer_events, peer_events_at);
    input_watch.Check(node);
    // In lockstep the checkpoints are taken at ticks, so that their contents do not depend on
    // when this loop woke up; in real time every checkpoint period of processed data.
    if (lockstep ? node.TakeCheckpointDue() : checkpoint_period > 0 && node.processed_until() >= next_checkpoint) {
      if (!health.stopped_at) {
        try {
          save_checkpoint();
          WriteOutputs(node, out_dir, lost_wall, refusals, health, /*final=*/false);
        } catch (const io::WriteError& e) {
          health.Failed(e, node.processed_until());
        }
      }
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
  pump();
  spdlog::info("signal {}: writing outputs to {}", shutdown.signal(), out_dir);
  // Tried even after a failure: the disk may have room again.
  std::optional<io::WriteError> final_failure;
  try {
    WriteOutputs(node, out_dir, lost_wall, refusals, health, /*final=*/true);
    if (checkpoint_period > 0) save_checkpoint();
  } catch (const io::WriteError& e) {
    health.Failed(e, node.processed_until());
    final_failure = e;
  }
  const AgentStats& st = node.stats();
  spdlog::info("done: t={:.1f}s odom={} scans={} landmarks={} global={} maps_received={} maps_dropped={}",
               node.processed_until(), node.sync_stats().odom_processed, node.sync_stats().scans_processed,
               node.LocalMap().size(), node.global().map.size(), st.maps_received, st.MapsDropped());
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
