#include "agent/agent_outputs.h"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <utility>

#include "common/map/wire_bytes.h"

namespace mapmesh {

using io::json;

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

// stats.json joining and ci_piecewise: the joining back-end's and the piecewise CI's counters.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(JoiningReport, solves, chains_held, chains, chains_joined, sources_by_ci, submaps,
                                   submaps_summarised, calibrated_solves, chains_calibrated, worst_variance_factor,
                                   iterations, converged, solved, ties, ties_dropped, first_passes, placed_alone,
                                   rechecks, rechecks_unchanged, rechecks_spared, relayed_chains, relayed_placed,
                                   relayed_alignments, relayed_disagreements, relayed_by_placement, placements_refused,
                                   superseded_chains, chains_extended)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(PiecewiseStats, submaps, fitted, refused, chained, pairs, rest)

namespace {

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

// Counts by reason as a JSON object, each reason's name (ToString) from first to count - 1.
template <typename Reason, typename Counts>
json ByReason(const Counts& counts, int first, int count) {
  json out = json::object();
  for (int i = first; i < count; ++i) out[std::string(ToString(static_cast<Reason>(i)))] = counts[i];
  return out;
}

// Each chain held: how many from index 0 without a gap, how many in all, and the digest of
// each of the first (FNV-1a of its bytes): two agents holding a submap hold the same bytes.
json ChainsJson(const SubmapBook& book) {
  json chains = json::array();
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
  return chains;
}

// stats.json submaps: the closed submaps held, sent and refused, and the open ones.
json SubmapsJson(const AgentNode& node) {
  const AgentStats& s = node.stats();
  const SubmapRelay::Counters& sc = node.submaps().counters();
  return json{{"own", sc.own},
              {"unsendable", s.submaps_unsendable},
              {"held", node.submaps().book().size()},
              {"held_bytes", node.submaps().book().bytes()},
              {"chains", ChainsJson(node.submaps().book())},
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
              {"rejected", ByReason<SubmapDecodeError>(s.submaps_rejected, 1, kSubmapDecodeErrorCount)},
              {"refused", ByReason<SubmapRefusal>(s.submaps_refused, 0, kSubmapRefusalCount)}};
}

// Creates path and its parents; io::WriteError when it cannot.
void CreateDirectories(const std::string& path) {
  std::error_code ec;
  std::filesystem::create_directories(path, ec);
  if (ec) throw io::WriteError(path, ec.value());
}

}  // namespace

bool OutputHealth::Failed(const io::WriteError& e, double t) {
  ++write_failures;
  if (stopped_at) return false;
  stopped_at = t;
  reason = e.what();
  return true;
}

json StatsJson(const AgentNode& node, const ShellCounts& shell, const OutputHealth& health) {
  const AgentStats& s = node.stats();
  const json rejected = ByReason<MapDecodeError>(s.maps_rejected, 1, kMapDecodeErrorCount);
  const json refused = ByReason<MapRefusal>(s.maps_refused, 0, kMapRefusalCount);
  // Lockstep: the peers' messages the inbox refused, by reason (lockstep_inbox.h).
  const json inbox_refused = ByReason<InboxRefusal>(node.inbox_refused(), 0, kInboxRefusalCount);
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
            {"submaps", SubmapsJson(node)},
            {"joining", node.exchange().joining()},
            {"ci_piecewise", node.exchange().piecewise()},
            {"impersonations_refused",
             {{"maps", ByRobot(shell.maps_impersonated)}, {"sightings", ByRobot(shell.sightings_impersonated)}}},
            {"not_from_feeder", {{"links", shell.links_not_from_feeder}, {"ticks", shell.ticks_not_from_feeder}}},
            {"transport_oversize", {{"dropped", shell.oversize_dropped}, {"max_sample_bytes", shell.max_sample_bytes}}},
            {"outputs",
             {{"write_failures", health.write_failures},
              {"stopped_at", health.stopped_at ? json(*health.stopped_at) : json()},
              {"reason", health.reason}}}});
  j.update(PeersJson(node, shell.peers_lost_wall));
  return j;
}

void WriteOutputs(const AgentNode& node, const std::string& dir, const ShellCounts& shell, const OutputHealth& health,
                  bool final) {
  CreateDirectories(dir + "/snapshots");
  const json local = io::MapToJson(node.LocalMap());
  const json global = io::GlobalMapToJson(node.global());
  io::WriteJsonAtomic(dir + "/local_map.json", local);
  io::WriteJsonAtomic(dir + "/global_map.json", global);
  json stats = StatsJson(node, shell, health);
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

std::vector<std::string> PeerEventLog::Update(const AgentNode& node) {
  std::vector<std::string> lines;
  if (node.exchange().updates() == updates_) return lines;
  updates_ = node.exchange().updates();
  for (const PeerReport& p : node.exchange().Peers()) {
    const PeerReport before = std::exchange(last_.try_emplace(p.key).first->second, p);
    const double t = node.processed_until();
    const std::string who = fmt::format("peer {}.{}{}", p.key.robot, p.key.incarnation,
                                        p.own_checkpoint ? " (own checkpoint)" : "");
    if (p.replaced > before.replaced) {
      lines.push_back(fmt::format("t={:.1f}s {}: frozen; re-placed where peer {}'s relay puts its landmarks", t, who,
                                  p.refuted_by));
    } else if (p.refuted > before.refuted) {
      lines.push_back(fmt::format("t={:.1f}s {}: our alignment refuted by peer {}'s relay; dropped", t, who,
                                  p.refuted_by));
    } else if (p.drops > before.drops) {
      lines.push_back(fmt::format("t={:.1f}s {}: alignment dropped after {} failed verifications", t, who,
                                  before.failures + 1));
    }
    if (p.aligned && (!before.aligned || p.corrections > before.corrections)) {
      lines.push_back(fmt::format("t={:.1f}s {}: {} at ({:.2f} m, {:.2f} m, {:.2f} deg){}", t, who,
                                  before.aligned ? "realigned" : "aligned", p.to_own.x, p.to_own.y,
                                  RadToDeg(p.to_own.theta), p.relayed ? ", relaying its global map" : ""));
    }
  }
  return lines;
}

std::optional<std::string> InputWatch::Check(const AgentNode& node, double now_s) {
  if (now_s < next_s_) return std::nullopt;
  const AgentStats& s = node.stats();
  const SyncStats y = node.sync_stats();
  const std::map<std::string, std::uint64_t> counts = {{"peer maps refused", s.MapsRefused()},
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
    next_s_ = now_s + 1.0;  // looked at once a second, not at every wake-up
    return std::nullopt;
  }
  if (s.maps_encode_failed > 0) what += fmt::format(" (last encoding error: {})", ToString(s.last_encode_error));
  next_s_ = now_s + 5.0;
  return fmt::format("t={:.1f}s input refused or lost: {}", node.processed_until(), what);
}

}  // namespace mapmesh
