// mapmesh-eval: scores the maps of a run directory against its truth.json (and, with
// --reference, against a reference map) and prints one JSON document on stdout (scripts/swarm
// merges it into summary.json).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <map>
#include <optional>
#include <random>
#include <vector>

#include "common/app/process.h"
#include "common/io/run_files.h"
#include "common/metrics/agent_evaluation.h"
#include "common/metrics/landmark_metrics.h"
#include "common/metrics/reference_metrics.h"
#include "common/metrics/trajectory_metrics.h"
#include "eval/dead_peers.h"

namespace mapmesh {
namespace {

using io::json;

// The span of the relative pose error (local.trajectory_rpe): one second, as `evo_rpe --delta 1
// --delta_unit s`.
constexpr double kRpeSpanS = 1.0;

json QualityJson(const MapQuality& q) {
  if (!q.evaluated) {
    return {{"landmarks", q.landmarks},    {"matched", nullptr},  {"rmse_m", nullptr}, {"nees_mean", nullptr},
            {"consistent_ratio", nullptr}, {"coverage", nullptr}, {"frame", "unknown"}};
  }
  return {{"landmarks", q.landmarks},
          {"matched", q.matched},
          {"rmse_m", q.rmse_m},
          {"nees_mean", q.nees_mean},
          {"consistent_ratio", q.consistent_ratio},
          {"coverage", q.coverage},
          {"frame", q.aligned ? "aligned" : "true_origin"}};
}

// What an agent left in its directory, read once.
struct AgentFiles {
  bool has_stats = false;
  json stats = json::object();
  std::optional<LandmarkMap> local;
  json global_json;  // null when absent
  std::optional<LandmarkMap> global;
  std::optional<Pose2> local_in_world;  // the local map's frame fitted to the truth by its signatures
};

AgentFiles ReadAgent(const std::string& dir, const io::RunTruth& truth) {
  AgentFiles f;
  if (std::filesystem::exists(dir + "/stats.json")) {
    f.has_stats = true;
    f.stats = io::ReadJson(dir + "/stats.json");
  }
  if (std::filesystem::exists(dir + "/local_map.json")) {
    f.local = io::MapFromJson(io::ReadJson(dir + "/local_map.json"));
    f.local_in_world = MapFrameInWorld(*f.local, truth.landmarks);
  }
  if (std::filesystem::exists(dir + "/global_map.json")) {
    f.global_json = io::ReadJson(dir + "/global_map.json");
    f.global = io::MapFromJson(f.global_json);
  }
  return f;
}

// Each robot's local landmarks' signatures, from its final local map (its last incarnation's;
// origins in an earlier incarnation keep matching by distance).
LocalSignatures KnownSignatures(const std::map<RobotId, AgentFiles>& files) {
  LocalSignatures known;
  for (const auto& [robot, f] : files) {
    if (!f.local || !f.has_stats || !f.stats.contains("incarnation")) continue;
    const auto incarnation = f.stats.at("incarnation").get<std::uint32_t>();
    for (const Landmark& l : f.local->landmarks) known[{robot, incarnation, l.id}] = l.signature;
  }
  return known;
}

// A global map's landmarks without a signature (its peers') signed by their origins
// (SignByOrigins), given the map's file; nullopt for a file written before origins from
// relayed maps were marked, which cannot tell them apart.
std::optional<OriginSigning> SignGlobalMap(const json& file, LandmarkMap& map, const LocalSignatures& known) {
  if (!file.value("origins_mark_relays", false)) return std::nullopt;
  std::vector<std::vector<LocalLandmark>> origins;
  for (const json& l : file.at("landmarks")) {
    origins.emplace_back();
    for (const json& o : l.value("origins", json::array())) {
      if (o.size() > 3 && o.at(3) == 1) continue;  // a relayed global map's id, not its robot's
      origins.back().emplace_back(o.at(0).get<RobotId>(), o.at(1).get<std::uint32_t>(), o.at(2).get<std::uint32_t>());
    }
  }
  return SignByOrigins(map, origins, known);
}

// Errors of the agent's alignments against the truth, keyed by peer ("3"; an older
// incarnation of a peer as "3@1"). trans_m is taken at the peer map's centroid, against the
// true start poses of both frames; trans_fit_m and rot_fit_rad against the frames the two
// maps are really in (their rigid fits to the truth), when both maps carry signatures.
json AlignmentErrors(const json& stats, const io::RunTruth& truth, const std::optional<Pose2>& origin,
                     const std::optional<Pose2>& own_fit, const std::map<RobotId, AgentFiles>& agents) {
  json out = json::object();
  if (!stats.contains("peers") || !origin || !truth.headings_known) return out;
  std::map<RobotId, std::uint32_t> latest;
  for (const json& p : stats.at("peers")) {
    if (p.value("aligned", false)) {
      const RobotId r = p.at("robot").get<RobotId>();
      latest[r] = std::max(latest[r], p.at("incarnation").get<std::uint32_t>());
    }
  }
  const TruePoseAt true_pose = [&](RobotId robot, double t) -> std::optional<Pose2> {
    const io::RobotTruth* rt = truth.Find(robot);
    return rt ? rt->PoseAt(t) : std::nullopt;
  };
  for (const json& p : stats.at("peers")) {
    if (!p.value("aligned", false)) continue;
    PlacedPeer peer;
    peer.robot = p.at("robot").get<RobotId>();
    peer.incarnation = p.at("incarnation").get<std::uint32_t>();
    peer.origin_stamp = p.at("origin_stamp").get<double>();
    peer.to_own = {p.at("transform").at(0).get<double>(), p.at("transform").at(1).get<double>(),
                   p.at("transform").at(2).get<double>()};
    peer.centroid = {p.at("centroid").at(0).get<double>(), p.at("centroid").at(1).get<double>()};
    // The peer's map as the run ended, when it is this incarnation's.
    std::optional<Pose2> peer_fit;
    const auto files = agents.find(peer.robot);
    if (files != agents.end() && files->second.local && files->second.has_stats &&
        files->second.stats.value("incarnation", 0u) == peer.incarnation) {
      peer_fit = files->second.local_in_world;
    }
    const std::optional<PlacementError> e = ScorePlacement(peer, *origin, true_pose, own_fit, peer_fit);
    if (!e) continue;
    json entry = {{"trans_m", e->from_start.translation_m},
                  {"rot_rad", e->from_start.rotation_rad},
                  {"incarnation", peer.incarnation},
                  {"own_checkpoint", p.value("own_checkpoint", false)}};
    if (e->from_fit) {
      entry["trans_fit_m"] = e->from_fit->translation_m;
      entry["rot_fit_rad"] = e->from_fit->rotation_rad;
    }
    const std::string robot = std::to_string(peer.robot);
    out[peer.incarnation == latest[peer.robot] ? robot : robot + "@" + std::to_string(peer.incarnation)] = entry;
  }
  return out;
}

// One reference map of reference.json, the frame it is in, and for a centralized optimum of
// several components each landmark's component (each is fitted on its own).
struct BatchReferenceMap {
  LandmarkMap map;
  bool in_world = false;
  std::map<std::int32_t, int> component;
};

std::optional<BatchReferenceMap> ReadReferenceMap(const json& j) {
  if (!j.is_object() || !j.contains("map")) return std::nullopt;
  BatchReferenceMap m;
  m.map = io::MapFromJson(j.at("map"));
  m.in_world = j.value("frame", "") == "world";
  const json components = j.value("landmark_component", json::object());
  for (const auto& [sig, c] : components.items()) {
    m.component[static_cast<std::int32_t>(std::stol(sig))] = c.get<int>();
  }
  return m;
}

// The run's reference maps (DIR/reference.json, written by mapmesh-lab reference): the fair
// centralized batch optimum (no start known), the one with every true start known, and each
// robot's own.
struct BatchReferenceMaps {
  std::optional<BatchReferenceMap> central, central_known_starts;
  std::map<RobotId, BatchReferenceMap> own;
};

std::optional<BatchReferenceMaps> ReadBatchReference(const std::string& path) {
  if (!std::filesystem::exists(path)) return std::nullopt;
  const json j = io::ReadJson(path);
  if (!j.value("available", false)) return std::nullopt;
  BatchReferenceMaps r;
  if (j.contains("central_known_starts")) {
    r.central = ReadReferenceMap(j.at("central"));
    r.central_known_starts = ReadReferenceMap(j.at("central_known_starts"));
  } else if (j.contains("central")) {
    // Written before the fair optimum (issue F1): its central optimum knew every true start.
    r.central_known_starts = ReadReferenceMap(j.at("central"));
  }
  const json own = j.value("own_batch", json::object());
  for (const auto& [id, m] : own.items()) {
    if (auto map = ReadReferenceMap(m)) r.own[static_cast<RobotId>(std::stoul(id))] = std::move(*map);
  }
  return r;
}

// A reference map on the landmarks `scored` matched (its truth_matched), after a rigid fit of
// those to the truth (of each component's on its own): the RMSE the optimum reaches on the same
// landmarks; null when fewer than two are shared.
json SameLandmarksRmse(const BatchReferenceMap& reference, const MapQuality& scored, const io::RunTruth& truth,
                       double gate_m) {
  if (!scored.evaluated) return json();
  const LandmarkMap same = RestrictToTruth(reference.map, scored.truth_matched);
  if (same.size() < 2) return json();
  const MapQuality q = EvaluateFittedParts(same, reference.component, truth.landmarks, truth.seen,
                                           reference.in_world ? std::optional<Pose2>(Pose2{}) : std::nullopt, gate_m);
  return q.evaluated && q.rmse_m > 0 ? json(q.rmse_m) : json();
}

// The centralized optimum of the data up to each of several times (DIR/reference_over_time.json,
// written by swarm run: mapmesh-lab reference --until ROBOT=T for every robot), by time.
std::vector<std::pair<double, BatchReferenceMap>> ReadReferenceOverTime(const std::string& path) {
  std::vector<std::pair<double, BatchReferenceMap>> out;
  if (!std::filesystem::exists(path)) return out;
  const json j = io::ReadJson(path);
  for (const json& sample : j.value("samples", json::array())) {
    if (!sample.is_object() || !sample.value("t", json()).is_number()) continue;
    if (auto m = ReadReferenceMap(sample.value("central", json()))) {
      out.emplace_back(sample.at("t").get<double>(), std::move(*m));
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  return out;
}

// The agent's history.jsonl with each snapshot's maps scored as the run went on.
// Global snapshots are signed by their origins as the final map is (SignGlobalMap).
json HistoryJson(const std::string& dir, const io::RobotTruth& robot, const io::RunTruth& truth, double gate_m,
                 const LocalSignatures& known, const std::vector<std::pair<double, BatchReferenceMap>>& over_time,
                 const BatchReferenceMap* final_central) {
  json out = json::array();
  std::vector<std::optional<MapQuality>> global_fits;  // per line: its global map after the rigid fit
  std::ifstream in(dir + "/history.jsonl");
  std::string text;
  while (std::getline(in, text)) {
    json line = json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (line.is_discarded() || !line.is_object()) continue;  // a line cut short by a kill
    std::optional<Pose2> origin = truth.headings_known ? robot.start : std::nullopt;
    const json& t = line.value("frame_origin_stamp", json());
    if (t.is_number() && truth.headings_known) origin = robot.PoseAt(t.get<double>());
    const std::string snapshot = line.value("snapshot", "");
    std::optional<Pose2> fit_start = origin;  // where the maps' frame is thought to lie, for the rigid fit
    std::optional<MapQuality> global_fit;
    for (const char* kind : {"local", "global"}) {
      const std::string path = dir + "/" + snapshot + "_" + kind + ".json";
      if (snapshot.empty() || !std::filesystem::exists(path)) continue;
      const json file = io::ReadJson(path);
      LandmarkMap map = io::MapFromJson(file);
      if (std::string(kind) == "global") SignGlobalMap(file, map, known);
      const MapQuality q = EvaluateOwnFrameMap(map, truth.landmarks, truth.seen, origin, gate_m);
      line[kind] = QualityJson(q);
      // As the final maps: after a rigid fit of the whole map to the truth (the global map's fit
      // starts where the local map's signatures put the frame when the origin is not known).
      if (!fit_start && std::string(kind) == "local") fit_start = MapFrameInWorld(map, truth.landmarks);
      const MapQuality aligned = EvaluateFittedMap(map, truth.landmarks, truth.seen, fit_start, gate_m);
      line[kind]["rmse_aligned_m"] = aligned.evaluated ? json(aligned.rmse_m) : json();
      if (std::string(kind) == "global") global_fit = aligned;
    }
    line.erase("snapshot");
    out.push_back(line);
    global_fits.push_back(global_fit);
  }
  // The gap over time: at each time the optimum was solved for, the global map of the latest
  // snapshot no later than it (and less than one snapshot period before it) over the optimum's
  // RMSE on the same landmarks; at the final snapshot, over the run's own optimum.
  const auto gap_at = [&](std::size_t i, const BatchReferenceMap& central, double sample_t) {
    if (!global_fits[i] || !global_fits[i]->evaluated) return;
    const json limit = SameLandmarksRmse(central, *global_fits[i], truth, gate_m);
    if (!limit.is_number()) return;
    out[i]["global"]["central_rmse_aligned_m"] = limit;
    out[i]["gap_to_central"] = global_fits[i]->rmse_m / limit.get<double>();
    out[i]["gap_solved_at"] = sample_t;
  };
  std::vector<double> times;
  for (const json& line : out) times.push_back(line.value("t", json()).is_number() ? line.at("t").get<double>() : NAN);
  std::vector<double> steps;
  for (std::size_t i = 1; i < times.size(); ++i) {
    if (times[i] > times[i - 1]) steps.push_back(times[i] - times[i - 1]);
  }
  std::sort(steps.begin(), steps.end());
  const double period = steps.empty() ? 0.0 : steps[steps.size() / 2];
  constexpr double kSameTime = 1e-6;
  for (const auto& [sample_t, central] : over_time) {
    std::optional<std::size_t> latest;
    for (std::size_t i = 0; i < times.size(); ++i) {
      if (times[i] <= sample_t + kSameTime && !out[i].value("final", false)) latest = i;
    }
    if (latest && sample_t - times[*latest] < std::max(period, kSameTime)) gap_at(*latest, central, sample_t);
  }
  if (final_central && !out.empty() && out.back().value("final", false)) {
    gap_at(out.size() - 1, *final_central, times.back());
  }
  return out;
}

// For each peer incarnation the agent saw go silent for good (its writer gone), what its global
// map holds of the last map received from it (dead_peers.h), in simulated worlds.
json DeadPeersJson(const json& stats, const std::optional<LandmarkMap>& local, const LandmarkMap& global,
                   const std::string& dir, const io::RunTruth& truth, const std::optional<Pose2>& origin,
                   double gate_m) {
  json out = json::array();
  if (!stats.contains("peers") || !origin || !truth.headings_known || !local) return out;
  const LandmarkMap& own = *local;
  for (const json& p : stats.at("peers")) {
    if (!p.value("stale", false) || p.value("own_checkpoint", false)) continue;
    const RobotId robot = p.at("robot").get<RobotId>();
    const std::uint32_t inc = p.at("incarnation").get<std::uint32_t>();
    const std::string path = dir + "/peers/" + std::to_string(robot) + "_" + std::to_string(inc) + "_local.json";
    const io::RobotTruth* rt = truth.Find(robot);
    if (!rt || !std::filesystem::exists(path)) continue;
    const std::optional<Pose2> peer_origin = rt->PoseAt(p.at("origin_stamp").get<double>());
    if (!peer_origin) continue;
    const HeldFromPeer h = CheckHeld(own, global, *origin, io::MapFromJson(io::ReadJson(path)), *peer_origin,
                                     truth.landmarks, gate_m);
    out.push_back({{"robot", robot},
                   {"incarnation", inc},
                   {"landmarks", h.landmarks},
                   {"alignable", h.alignable()},
                   {"aligned_tries", h.aligned_tries},
                   {"overlaps", h.overlaps},
                   {"verdict", h.verdict},
                   {"covered", h.covered},
                   {"inliers", h.inliers},
                   {"held", h.held},
                   {"aligned", p.value("aligned", false)}});
  }
  return out;
}

json ReferenceJson(const ReferenceQuality& q) {
  json j = {{"aligned", q.aligned}, {"landmarks", q.landmarks}, {"reference_landmarks", q.reference_landmarks}};
  if (!q.aligned) return j;
  j.update({{"matched", q.matched},
            {"duplicates", q.duplicates},
            {"extra", q.extra},
            {"reference_coverage", q.reference_coverage},
            {"rmse_m", q.rmse_m},
            {"nees_mean", q.nees_mean},
            {"to_reference", {q.to_reference.x, q.to_reference.y, q.to_reference.theta}}});
  return j;
}

int Run(int argc, char** argv) {
  CLI::App cli{"mapmesh-eval: scores a run's maps against its ground truth (JSON on stdout)"};
  std::string run_dir;
  double gate_m = 2.0;
  cli.add_option("--run", run_dir, "run directory (holds truth.json and agent_<id>/)")->required();
  cli.add_option("--gate", gate_m, "metres: landmarks without a signature match the nearest true one within this");
  std::string reference_path;
  cli.add_option("--reference", reference_path,
                 "also score every map against this reference map (a map JSON, say the whole run as one agent): "
                 "aligned to it by geometry, matched to its nearest landmark within --gate; for data without "
                 "landmark truth")
      ->check(CLI::ExistingFile);
  if (auto code = app::ParseArgs(cli, "mapmesh-eval", argc, argv)) return *code;
  std::optional<LandmarkMap> reference;
  if (!reference_path.empty()) reference = io::MapFromJson(io::ReadJson(reference_path));
  std::mt19937_64 rng(1);
  const io::RunTruth truth = io::TruthFromJson(io::ReadJson(run_dir + "/truth.json"));
  const std::optional<BatchReferenceMaps> batch = ReadBatchReference(run_dir + "/reference.json");
  const std::vector<std::pair<double, BatchReferenceMap>> over_time = ReadReferenceOverTime(
      run_dir + "/reference_over_time.json");
  std::map<RobotId, AgentFiles> files;
  for (const io::RobotTruth& robot : truth.robots) {
    files[robot.id] = ReadAgent(run_dir + "/agent_" + std::to_string(robot.id), truth);
  }
  const LocalSignatures known = KnownSignatures(files);
  std::map<RobotId, OriginSigning> signing;
  for (auto& [robot, f] : files) {
    if (!f.global) continue;
    if (const auto s = SignGlobalMap(f.global_json, *f.global, known)) signing[robot] = *s;
  }
  json agents = json::object();
  for (const io::RobotTruth& robot : truth.robots) {
    const std::string dir = run_dir + "/agent_" + std::to_string(robot.id);
    const AgentFiles& f = files.at(robot.id);
    json entry = json::object();
    // A map's frame is the robot's pose when its agent's session began: the start of the run,
    // or later for a restarted agent (its stats.json says when). Without a known pose the
    // map is rigidly aligned to the truth.
    std::optional<Pose2> origin = robot.start;
    const json& stats = f.stats;
    if (f.has_stats) {
      const json& t = stats.value("frame_origin_stamp", json());
      if (t.is_number() && truth.headings_known) origin = robot.PoseAt(t.get<double>());
      if (t.is_number() && !truth.headings_known) origin.reset();
    }
    // Without a known origin the local map is fitted to the truth by its signatures; the global
    // map shares the local map's frame but not its signatures (fused landmarks carry none), so it
    // is scored in the frame fitted from the local map.
    const std::optional<Pose2> local_fit = origin ? std::nullopt : f.local_in_world;
    std::optional<Pose2> local_to_reference;
    for (const char* kind : {"local", "global"}) {
      const std::optional<LandmarkMap>& file = std::string(kind) == "local" ? f.local : f.global;
      if (!file) continue;
      const LandmarkMap& map = *file;
      const bool fitted = !origin && local_fit && std::string(kind) == "global";
      entry[kind] = QualityJson(EvaluateOwnFrameMap(map, truth.landmarks, truth.seen, fitted ? local_fit : origin,
                                                    gate_m));
      if (fitted) entry[kind]["frame"] = "local_map_fit";
      if (const auto s = signing.find(robot.id); std::string(kind) == "global" && s != signing.end()) {
        entry[kind]["signed_by_origins"] = s->second.signed_count;
        entry[kind]["identities_mixed"] = s->second.mixed;
      }
      // The same map after a least-squares rigid fit of all of it to the truth, whatever its
      // origin: the error of its shape alone (relayed landmarks included in a global map).
      const MapQuality aligned = EvaluateFittedMap(map, truth.landmarks, truth.seen, origin ? origin : f.local_in_world,
                                                   gate_m);
      entry[kind]["rmse_aligned_m"] = aligned.evaluated ? json(aligned.rmse_m) : json();
      entry[kind]["fit_in_world"] = aligned.evaluated && aligned.fit
                                        ? json{aligned.fit->x, aligned.fit->y, aligned.fit->theta}
                                        : json();
      // The limit on the same landmarks (docs/EXPERIMENTS.md "The limit"): the global map against
      // the centralized batch optimum, the local map against the robot's own batch optimum; and
      // the ratio of the two RMSEs after a rigid fit, the map's gap to its limit.
      if (batch) {
        const bool local = std::string(kind) == "local";
        const auto own = batch->own.find(robot.id);
        json limit;
        if (!local && batch->central) {
          limit = SameLandmarksRmse(*batch->central, aligned, truth, gate_m);
          entry[kind]["central_rmse_aligned_m"] = limit;
        } else if (local && own != batch->own.end()) {
          limit = SameLandmarksRmse(own->second, aligned, truth, gate_m);
          entry[kind]["own_batch_rmse_aligned_m"] = limit;
        }
        if (limit.is_number() && aligned.evaluated) {
          entry[local ? "gap_to_own_batch" : "gap_to_central"] = aligned.rmse_m / limit.get<double>();
        }
        // Beside it, the optimum that knows every robot's true start (what no agent knows).
        if (!local && batch->central_known_starts) {
          const json known = SameLandmarksRmse(*batch->central_known_starts, aligned, truth, gate_m);
          entry[kind]["central_known_starts_rmse_aligned_m"] = known;
          if (known.is_number() && aligned.evaluated) {
            entry["gap_to_central_known_starts"] = aligned.rmse_m / known.get<double>();
          }
        }
        // The global map against the optimum of the information that reached the agent (each
        // robot's data up to when the agent last received any of it: agent_<id>/
        // reference_reached.json, written where that is less than the whole run), else against
        // the central optimum: a map cannot hold what never reached it.
        if (!local) {
          const std::optional<BatchReferenceMaps> reached = ReadBatchReference(dir + "/reference_reached.json");
          json within = limit;
          if (reached && reached->central) {
            within = SameLandmarksRmse(*reached->central, aligned, truth, gate_m);
            entry[kind]["reached_rmse_aligned_m"] = within;
          }
          if (within.is_number() && aligned.evaluated) entry["gap_to_reached"] = aligned.rmse_m / within.get<double>();
          // How much of what reached the agent its map holds (issue J2): the landmarks of the
          // optimum of what reached it (every one a robot whose data reached it saw by then).
          const BatchReferenceMap* of = reached && reached->central ? &*reached->central
                                        : batch->central            ? &*batch->central
                                                                    : nullptr;
          const std::optional<double> c = of && aligned.evaluated ? CoverageOf(of->map, aligned.truth_matched)
                                                                  : std::nullopt;
          entry[kind]["coverage_reached"] = c ? json(*c) : json();
        }
      }
      if (reference) {
        // The global map is in the local map's frame: it is placed where the local map aligned.
        const ReferenceQuality rq = CompareToReference(map, *reference, gate_m, AlignmentOptions{}, rng,
                                                       std::string(kind) == "global" ? local_to_reference
                                                                                     : std::nullopt);
        if (std::string(kind) == "local" && rq.aligned) local_to_reference = rq.to_reference;
        entry[kind]["reference"] = ReferenceJson(rq);
        entry[kind]["reference"]["frame"] = std::string(kind) == "global" ? "local_map_alignment" : "alignment";
      }
    }
    // The global map restricted to the landmarks this agent mapped itself (its local map is
    // one of their inputs): fusion must not make them worse.
    if (entry.contains("global") && stats.contains("incarnation")) {
      const json& g = f.global_json;
      const LandmarkMap& map = *f.global;
      LandmarkMap own;
      const auto self_inc = stats.at("incarnation").get<std::uint32_t>();
      for (std::size_t i = 0; i < map.size(); ++i) {
        for (const json& o : g.at("landmarks").at(i).value("origins", json::array())) {
          if (o.at(0).get<RobotId>() == robot.id && o.at(1).get<std::uint32_t>() == self_inc) {
            own.landmarks.push_back(map.landmarks[i]);
            break;
          }
        }
      }
      const MapQuality q = EvaluateOwnFrameMap(own, truth.landmarks, truth.seen, origin, gate_m);
      entry["global"]["rmse_own_landmarks_m"] = q.evaluated && q.matched > 0 ? json(q.rmse_m) : json();
      entry["alignment_errors"] = AlignmentErrors(stats, truth, origin, f.local_in_world, files);
      entry["dead_peers"] = DeadPeersJson(stats, f.local, map, dir, truth, origin, gate_m);
    }
    // The estimated trajectory against the true one: in the true frame when the origin is
    // known, else after a rigid fit (GPS glitches dropped).
    if (entry.contains("local") && std::filesystem::exists(dir + "/trajectory.json") && !robot.trajectory.empty()) {
      std::vector<TimedPosition> est, ref;
      const json traj = io::ReadJson(dir + "/trajectory.json");
      for (const auto& p : traj.at("poses")) {
        est.push_back({p.at(0).get<double>(), {p.at(1).get<double>(), p.at(2).get<double>()}});
      }
      for (const io::TruthSample& s : robot.trajectory) {
        if (origin) {
          const Pose2 rel = origin->Inverse() * s.pose;
          ref.push_back({s.t, {rel.x, rel.y}});
        } else {
          ref.push_back({s.t, {s.pose.x, s.pose.y}});
        }
      }
      const TrajectoryError e = origin ? CompareTrajectory(est, ref, false)
                                       : CompareTrajectory(est, DropImplausibleFixes(ref, 20.0), true);
      entry["local"]["trajectory_rmse_m"] = e.samples > 0 ? json(e.rmse_m) : json();
      entry["local"]["trajectory_frame"] = origin ? "true_origin" : "aligned";
      // The absolute trajectory error after a rigid fit (evo_ape --align), and the relative pose
      // error over 1 s spans (evo_rpe --delta 1 --delta_unit s: needs true headings).
      const TrajectoryError ate = origin ? CompareTrajectory(est, ref, true) : e;
      entry["local"]["trajectory_ate_aligned_m"] = ate.samples > 0 ? json(ate.rmse_m) : json();
      json rpe;
      if (truth.headings_known) {
        std::vector<PoseStamp> est_poses, ref_poses;
        for (const auto& p : traj.at("poses")) {
          est_poses.push_back({p.at(0).get<double>(),
                               Pose2{p.at(1).get<double>(), p.at(2).get<double>(), p.at(3).get<double>()}});
        }
        for (const io::TruthSample& s : robot.trajectory) ref_poses.push_back({s.t, s.pose});
        const RelativeTrajectoryError r = CompareRelativePoses(est_poses, ref_poses, kRpeSpanS);
        if (r.pairs > 0) {
          rpe = {{"delta_s", kRpeSpanS},
                 {"pairs", r.pairs},
                 {"translation_rmse_m", r.translation_rmse_m},
                 {"rotation_rmse_deg", r.rotation_rmse_rad * 180.0 / M_PI}};
        }
      }
      entry["local"]["trajectory_rpe"] = rpe;
    }
    // Where the final map frame lies in the world (for drawing): the true pose at its origin,
    // else its rigid fit by signatures, else unknown.
    const std::optional<Pose2> frame = origin ? origin : f.local_in_world;
    entry["frame_in_world"] = frame ? json{frame->x, frame->y, frame->theta} : json();
    entry["history"] = HistoryJson(dir, robot, truth, gate_m, known, over_time,
                                   batch && batch->central ? &*batch->central : nullptr);
    agents[std::to_string(robot.id)] = entry;
  }
  std::printf("%s\n", json{{"agents", agents}, {"seen_landmarks", truth.seen.size()}}.dump(1).c_str());
  return 0;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-eval", [&] { return mapmesh::Run(argc, argv); });
}
