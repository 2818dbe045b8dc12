#include "lab/bus_swarm.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "agent/agent_setup.h"
#include "common/check.h"
#include "common/metrics/agent_evaluation.h"
#include "common/metrics/trajectory_metrics.h"
#include "sim_feeder/sources.h"

namespace mapmesh::lab {
namespace {

// Keeps what an agent publishes until the bus delivers it.
class Outbox : public AgentOutput {
 public:
  void PublishMap(const MapMessage& m) override { maps.push_back(m); }
  void PublishStatus(const AgentStatus&) override {}
  void PublishSighting(const Sighting& s) override { sightings.push_back(s); }
  std::vector<MapMessage> maps;
  std::vector<Sighting> sightings;
};

struct Slot {
  RobotId id = 0;
  std::uint32_t incarnation = 0;
  std::unique_ptr<Outbox> out;
  std::unique_ptr<AgentNode> node;
  bool alive = false;
  std::optional<AgentCheckpoint> checkpoint;
  double next_checkpoint_s = 0.0;
};

}  // namespace

BusSwarmResult RunBusSwarm(const Scenario& scenario_in, const BusSwarmOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  Scenario sc = scenario_in;
  Feed feed = MakeFeed(sc, o.datasets_root);
  const double checkpoint_period = sc.agent.checkpoint_period_s;

  std::map<RobotId, Slot> slots;
  auto launch = [&](Slot& s) {
    ++s.incarnation;
    s.out = std::make_unique<Outbox>();
    s.node = std::make_unique<AgentNode>(sc.agent, AgentRunFor(sc, s.id), s.id, s.incarnation, *s.out);
    if (s.checkpoint) s.node->Resume(*s.checkpoint);
    s.alive = true;
    s.next_checkpoint_s = 0.0;
  };
  for (const RobotSpec& r : sc.robots) {
    Slot& s = slots[r.id];
    s.id = r.id;
    launch(s);
  }
  auto kills = o.kills, restarts = o.restarts;
  std::sort(kills.begin(), kills.end());
  std::sort(restarts.begin(), restarts.end());
  std::size_t next_kill = 0, next_restart = 0;
  std::map<RobotId, std::vector<GroundTruth>> truth;
  std::optional<RadioLinks> links;
  std::map<std::pair<RobotId, MapKind>, MapMessage> latest;  // what a late joiner gets (transient-local)
  // The worst transform each agent (incarnation) used for each peer frame, against the truth then.
  std::map<std::pair<std::pair<RobotId, std::uint32_t>, PeerKey>, BusAgentResult::WorstAlignment> used;
  std::map<RobotId, std::uint64_t> sampled_update;
  const std::vector<Eigen::Vector2d>& landmark_truth = feed.source->Truth().landmarks;
  BusSwarmResult result;
  auto Kill = [&](RobotId robot) {
    Slot& s = slots.at(robot);
    if (!s.alive) return;
    s.alive = false;
    latest.erase({s.id, MapKind::kLocal});  // a dead writer's data goes with it
    latest.erase({s.id, MapKind::kGlobal});
    for (auto& [id, other] : slots) {
      if (other.alive) other.node->OnPeerLiveliness(s.id, false);
    }
  };
  auto Restart = [&](RobotId robot) {
    Slot& s = slots.at(robot);
    if (s.alive) return;
    launch(s);
    if (links) s.node->OnLinks(*links);
    for (const auto& [key, msg] : latest) s.node->OnMap(msg);  // a late joiner's history (transient-local)
  };
  // The worst transform each agent used for each peer frame, sampled after each exchange update.
  auto SampleAlignments = [&]() {
    for (auto& [id, s] : slots) {
      if (landmark_truth.empty() || !s.alive || s.node->exchange().updates() == sampled_update[id]) continue;
      sampled_update[id] = s.node->exchange().updates();
      std::optional<std::optional<Pose2>> own_now;
      for (const PeerReport& p : s.node->exchange().Peers()) {
        if (!p.aligned || p.own_checkpoint) continue;
        const Slot& peer = slots.at(p.key.robot);
        if (!peer.alive || peer.incarnation != p.key.incarnation) continue;
        if (!own_now) own_now = MapFrameInWorld(s.node->LocalMap(), landmark_truth);
        const std::optional<Pose2> peer_now = MapFrameInWorld(peer.node->LocalMap(), landmark_truth);
        if (!*own_now || !peer_now) continue;
        const TransformError e = CompareTransforms(p.to_own, (*own_now)->Inverse() * *peer_now, p.centroid);
        BusAgentResult::WorstAlignment& w = used[{{id, s.incarnation}, p.key}];
        w.peer = p.key;
        ++w.transforms;
        w.translation_m = std::max(w.translation_m, e.translation_m);
        w.rotation_rad = std::max(w.rotation_rad, e.rotation_rad);
      }
    }
  };

  // The lockstep exchange (messages.h ExchangeTick) as the feeder runs it: at the batch that
  // crosses an exchange point, every live agent's exchange phase, the messages delivered, and
  // the deliver phase; then the kills and restarts of that batch (the feeder's holds).
  const bool ticks = sc.feeder.pace == Pace::kLockstep;
  const double exchange_period = sc.agent.exchange.map_publish_period_s;
  double next_exchange = exchange_period;
  auto tick_for = [&](double t) -> std::optional<std::uint32_t> {
    if (!ticks || t + 1e-9 < next_exchange) return std::nullopt;
    const double k = std::floor((t + 1e-9) / exchange_period);
    next_exchange = (k + 1.0) * exchange_period;
    return static_cast<std::uint32_t>(k);
  };
  // What a test does to a robot's sightings and answers on their way (withheld, or shifted),
  // on their own or riding on its maps (lockstep).
  auto tamper = [&](RobotId id, std::vector<Sighting>& v) {
    if (o.sightings_withheld.count(id)) v.clear();
    if (const auto off = o.sighting_offsets.find(id); off != o.sighting_offsets.end()) {
      for (Sighting& m : v) {
        m.x += off->second.x();
        m.y += off->second.y();
      }
    }
  };
  // Delivers what the agents published, in robot order: maps, then sightings.
  auto deliver = [&]() {
    std::map<std::pair<RobotId, std::uint32_t>, std::uint32_t> sent;
    std::vector<MapMessage> bus;
    for (auto& [id, s] : slots) {
      if (!s.out) continue;
      for (MapMessage& m : s.out->maps) tamper(id, m.sightings);
      bus.insert(bus.end(), s.out->maps.begin(), s.out->maps.end());
      sent[{id, s.incarnation}] += static_cast<std::uint32_t>(s.out->maps.size());
      s.out->maps.clear();
    }
    for (const MapMessage& m : bus) {
      latest[{m.robot_id, m.kind}] = m;
      for (auto& [id, s] : slots) {
        if (s.alive && id != m.robot_id) s.node->OnMap(m);
      }
    }
    std::vector<Sighting> sightings;
    for (auto& [id, s] : slots) {
      if (!s.out) continue;
      tamper(id, s.out->sightings);  // realtime only: in lockstep they ride on the maps
      sightings.insert(sightings.end(), s.out->sightings.begin(), s.out->sightings.end());
      s.out->sightings.clear();
    }
    for (const Sighting& m : sightings) {
      for (auto& [id, s] : slots) {
        if (s.alive && id != m.robot_id) s.node->OnSighting(m);
      }
    }
    return sent;
  };
  std::optional<std::uint32_t> last_tick;
  auto exchange = [&](std::uint32_t k, double stamp) {
    last_tick = k;
    ExchangeTick tick;
    tick.index = k;
    tick.stamp = stamp;
    tick.links = links ? *links : RadioLinks{-1.0, {}};
    for (auto& [id, s] : slots) {
      if (s.alive) tick.peers.push_back({id, s.incarnation, 0});
    }
    for (auto& [id, s] : slots) {
      if (s.alive) MAPMESH_CHECK(s.node->OnTick(tick), "the bus delivers every link table at once");
    }
    const auto sent = deliver();
    tick.phase = TickPhase::kDeliver;
    for (TickPeer& p : tick.peers) {
      const auto it = sent.find({p.robot, p.incarnation});
      p.messages = it == sent.end() ? 0 : it->second;
    }
    for (auto& [id, s] : slots) {
      if (!s.alive) continue;
      MAPMESH_CHECK(s.node->OnTick(tick), "the bus delivers every message at once");
      if (s.node->TakeCheckpointDue()) s.checkpoint = s.node->Checkpoint();
    }
  };

  double end_stamp = 0.0;
  while (!feed.source->Done()) {
    FeedBatch b = feed.source->Next();
    const double t = b.stamp;
    end_stamp = t;
    if (!ticks) {  // in real time the writer's liveliness tells the others at once
      for (; next_kill < kills.size() && kills[next_kill].first <= t; ++next_kill) Kill(kills[next_kill].second);
      for (; next_restart < restarts.size() && restarts[next_restart].first <= t; ++next_restart)
        Restart(restarts[next_restart].second);
    }
    if (b.links) {
      links = b.links;
      for (auto& [id, s] : slots) {
        if (s.alive) s.node->OnLinks(*b.links);
      }
    }
    for (const Scan& scan : b.scans) {
      Slot& s = slots.at(scan.robot_id);
      if (s.alive) s.node->OnScan(AsOnTheWire(scan));
    }
    for (const Odometry& od : b.odom) {
      Slot& s = slots.at(od.robot_id);
      if (s.alive) s.node->OnOdometry(od);
    }
    for (const GroundTruth& g : b.truth) truth[g.robot_id].push_back(g);
    for (auto& [id, s] : slots) {
      if (ticks || !s.alive || checkpoint_period <= 0 || s.node->processed_until() + 1e-9 < s.next_checkpoint_s)
        continue;
      s.checkpoint = s.node->Checkpoint();
      s.next_checkpoint_s = s.node->processed_until() + checkpoint_period;
    }
    if (const std::optional<std::uint32_t> k = tick_for(t)) exchange(*k, *k * exchange_period);
    SampleAlignments();
    if (!ticks) {
      deliver();
      continue;
    }
    // The feeder's holds: after the batch's barrier and its exchange tick.
    for (; next_kill < kills.size() && kills[next_kill].first <= t; ++next_kill) Kill(kills[next_kill].second);
    for (; next_restart < restarts.size() && restarts[next_restart].first <= t; ++next_restart)
      Restart(restarts[next_restart].second);
  }

  // The feeder's closing tick: the maps published at the last exchange point are applied too.
  if (last_tick) exchange(*last_tick + 1, end_stamp);

  const WorldTruth& world = feed.source->Truth();
  result.landmarks = world.landmarks;
  for (std::size_t i = 0; i < world.seen.size(); ++i) {
    if (world.seen[i]) result.seen.push_back(static_cast<int>(i));
  }
  for (auto& [id, s] : slots) {
    BusAgentResult r;
    r.robot = id;
    r.incarnation = s.incarnation;
    r.alive_at_end = s.alive;
    double origin_stamp = 0.0;
    if (s.alive) {
      r.local = s.node->LocalMap();
      r.global = s.node->global();
      r.trajectory = s.node->trajectory();
      r.frame_origin_stamp = s.node->frame_origin_stamp();
      r.peers = s.node->exchange().Peers();
      r.stats = s.node->stats();
      origin_stamp = s.node->frame_origin_stamp().value_or(0.0);
    } else if (s.checkpoint) {  // a dead agent leaves its last checkpoint
      r.local = s.checkpoint->local;
      r.global.map = s.checkpoint->global;
      origin_stamp = s.checkpoint->origin_stamp;
    }
    if (world.headings_known) r.origin_truth = TruthAt(truth[id], origin_stamp);
    if (!world.landmarks.empty()) {
      r.local_quality = EvaluateOwnFrameMap(r.local, world.landmarks, result.seen, r.origin_truth);
      r.global_quality = EvaluateOwnFrameMap(r.global.map, world.landmarks, result.seen, r.origin_truth);
      r.global_fitted = EvaluateOwnFrameMap(r.global.map, world.landmarks, result.seen, std::nullopt);
    }
    const TruePoseAt true_pose = [&](RobotId robot, double t) { return TruthAt(truth[robot], t); };
    const std::optional<Pose2> own_fit = world.landmarks.empty() ? std::nullopt
                                                                 : MapFrameInWorld(r.local, world.landmarks);
    for (const PeerReport& p : r.peers) {
      if (!p.aligned || !r.origin_truth || !world.headings_known) continue;
      // The peer's map as the run ended, when it is this incarnation's.
      std::optional<Pose2> peer_fit;
      const Slot& peer = slots.at(p.key.robot);
      if (own_fit && peer.alive && peer.incarnation == p.key.incarnation) {
        peer_fit = MapFrameInWorld(peer.node->LocalMap(), world.landmarks);
      }
      const std::optional<PlacementError> e = ScorePlacement({p.key.robot, p.key.incarnation, p.to_own, p.centroid,
                                                              p.origin_stamp},
                                                             *r.origin_truth, true_pose, own_fit, peer_fit);
      if (!e) continue;
      BusAgentResult::AlignmentError err{p.key, e->from_start.translation_m, e->from_start.rotation_rad};
      if (e->from_fit) {
        err.fit_translation_m = e->from_fit->translation_m;
        err.fit_rotation_rad = e->from_fit->rotation_rad;
      }
      r.alignment_errors.push_back(err);
    }
    for (const auto& [k, w] : used) {
      if (k.first == std::make_pair(id, s.incarnation)) r.worst_alignments.push_back(w);
    }
    result.agents.push_back(std::move(r));
  }
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace mapmesh::lab
