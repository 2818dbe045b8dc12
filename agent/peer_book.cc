#include "agent/peer_book.h"

#include <algorithm>

namespace mapmesh {

PeerBook::Receipt PeerBook::OnPeerMap(RobotId robot, std::uint32_t incarnation, MapKind kind, std::uint32_t version,
                                      double origin_stamp, LandmarkMap map, double now) {
  const PeerKey key{robot, incarnation};
  auto it = peers_.find(key);
  // Versions count publications: no publisher can be further ahead than its maps could go out.
  const double rate = options_.MaxVersionsPerS();
  if (version > options_.version_slack + rate * std::max(0.0, now)) return Receipt::kVersionJump;
  if (it != peers_.end()) {
    const PeerState& known = it->second;
    const bool has = kind == MapKind::kLocal ? known.has_local : known.has_global;
    const std::uint32_t last = kind == MapKind::kLocal ? known.local_version : known.global_version;
    const double heard = kind == MapKind::kLocal ? known.local_heard : known.global_heard;
    if (has && version <= last) return Receipt::kStaleVersion;
    if (has && version - last > options_.version_slack + rate * std::max(0.0, now - heard))
      return Receipt::kVersionJump;
  } else if (!MakeRoomFor(robot, now)) {
    return Receipt::kTooManyIncarnations;
  }
  PeerState& p = peers_[key];
  p.key = key;
  if (kind == MapKind::kLocal) {
    p.local_version = version;
    p.local_heard = now;
    p.local = std::move(map);
    p.has_local = true;
  } else {
    p.global_version = version;
    p.global_heard = now;
    p.global = std::move(map);
    p.has_global = true;
  }
  p.origin_stamp = origin_stamp;
  // A later incarnation of a robot whose session began where an aligned earlier one's did (the
  // feeder replayed its stream to it): the same frame. The earlier one's transform waits to be
  // weighed like a rendezvous fit, verified on the maps before it is used, instead of a search
  // from nothing on every restart (which found a false 92 degrees in a restart storm).
  SeedContinuityPrior(p);
  p.last_heard = now;
  p.changed = true;
  p.stale = false;  // heard again: it speaks for itself
  p.superseded_by.reset();
  if (p.stage == PeerStage::kSuperseded) p.stage = PeerStage::kAligned;
  return Receipt::kAccepted;
}

void PeerBook::SeedContinuityPrior(PeerState& p) const {
  if (p.Aligned() || p.rendezvous || p.own_checkpoint) return;
  const auto seed = [&p](const Pose2& transform, const Eigen::Matrix3d& cov) {
    AlignmentResult prior;
    prior.verdict = AlignmentVerdict::kAccepted;
    prior.transform = transform;
    prior.cov = cov;
    p.rendezvous = prior;
    p.continuity_prior = true;
  };
  for (const auto& [k, q] : peers_) {
    if (k.robot != p.key.robot || k.incarnation >= p.key.incarnation || !q.Aligned() ||
        q.origin_stamp != p.origin_stamp) {
      continue;
    }
    seed(q.to_own, q.to_own_cov);
    return;
  }
  if (!carried_frame_) return;
  // The newest carried incarnation of the robot, up to p's, in p's frame.
  const PeerAlignment* best = nullptr;
  for (const PeerAlignment& a : carried_) {
    if (a.frame_stamp != *carried_frame_ || a.robot != p.key.robot || a.incarnation > p.key.incarnation ||
        a.origin_stamp != p.origin_stamp) {
      continue;
    }
    if (best == nullptr || a.incarnation > best->incarnation) best = &a;
  }
  if (best != nullptr) seed(best->to_own, best->cov);
}

void PeerBook::AddCarried(std::vector<PeerAlignment> carried) {
  for (PeerAlignment& a : carried) {
    if (a.robot == self_) continue;
    const auto same = [&a](const PeerAlignment& b) { return b.robot == a.robot && b.incarnation == a.incarnation; };
    if (std::none_of(carried_.begin(), carried_.end(), same)) carried_.push_back(a);
  }
}

int PeerBook::UseCarriedIn(double frame_stamp) {
  carried_frame_ = frame_stamp;
  int waiting = 0;
  for (auto& [key, p] : peers_) {
    const bool had = p.rendezvous.has_value();
    SeedContinuityPrior(p);
    waiting += !had && p.rendezvous.has_value();
  }
  return waiting;
}

std::vector<PeerAlignment> PeerBook::Alignments(double frame_stamp) const {
  std::vector<PeerAlignment> out;
  for (const auto& [key, p] : peers_) {
    if (p.own_checkpoint || !p.Aligned()) continue;
    PeerAlignment a;
    a.robot = key.robot;
    a.incarnation = key.incarnation;
    a.origin_stamp = p.origin_stamp;
    a.frame_stamp = frame_stamp;
    a.to_own = p.to_own;
    a.cov = 0.5 * (p.to_own_cov + p.to_own_cov.transpose());
    out.push_back(a);
  }
  const std::size_t placed = out.size();
  for (const PeerAlignment& a : carried_) {
    const auto same = [&a](const PeerAlignment& b) { return b.robot == a.robot && b.incarnation == a.incarnation; };
    if (std::none_of(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(placed), same)) out.push_back(a);
  }
  return out;
}

bool PeerBook::MakeRoomFor(RobotId robot, double now) {
  std::vector<PeerStates::iterator> kept;
  for (auto it = peers_.lower_bound({robot, 0}); it != peers_.end() && it->first.robot == robot; ++it)
    kept.push_back(it);
  if (static_cast<int>(kept.size()) < options_.max_incarnations) return true;
  // Evict the incarnation heard longest ago among those that never contributed and can no
  // longer speak; one that did contribute stays (nothing learned is lost).
  auto victim = peers_.end();
  for (auto it : kept) {
    const PeerState& p = it->second;
    if (p.ever_aligned || p.own_checkpoint || !p.Silent(now, options_.SilentAfterS())) continue;
    if (victim == peers_.end() || p.last_heard < victim->second.last_heard) victim = it;
  }
  if (victim == peers_.end()) return false;
  peers_.erase(victim);
  return true;
}

void PeerBook::SetStale(PeerState& p, bool stale, double now) {
  if (stale && !p.stale) p.stale_since = now;
  p.stale = stale;
}

void PeerBook::OnPeerLiveliness(RobotId robot, bool alive, double now) {
  for (auto& [key, p] : peers_) {
    if (key.robot == robot && !p.own_checkpoint) SetStale(p, !alive, now);
  }
}

void PeerBook::SetLive(const std::set<PeerKey>& live, double now) {
  for (auto& [key, p] : peers_) {
    if (!p.own_checkpoint) SetStale(p, live.count(key) == 0, now);
  }
}

void PeerBook::AddOwnCheckpoint(std::uint32_t incarnation, double origin_stamp, LandmarkMap local, LandmarkMap global) {
  PeerState& p = peers_[{self_, incarnation}];
  p.key = {self_, incarnation};
  p.own_checkpoint = true;
  p.stale = true;  // that process is gone; its maps stay
  p.origin_stamp = origin_stamp;
  p.local = std::move(local);
  p.global = std::move(global);
  p.has_local = true;
  p.has_global = !p.global.empty();
  p.changed = true;
}

bool PeerBook::CarriedByLater(const PeerState& p) const {
  if (p.own_checkpoint) return false;
  const std::size_t size = p.Map().size();
  for (auto it = peers_.upper_bound(p.key); it != peers_.end() && it->first.robot == p.key.robot; ++it) {
    const PeerState& later = it->second;
    if (later.origin_stamp == p.origin_stamp && later.Map().size() >= size) return true;
  }
  return false;
}

std::vector<PeerFacts> PeerBook::Facts(double now) const {
  std::vector<PeerFacts> facts;
  facts.reserve(peers_.size());
  for (const auto& [key, p] : peers_) {
    PeerFacts f;
    f.key = key;
    f.has_map = p.has_local || p.has_global;
    f.aligned = p.Aligned();
    f.aligned_by_overlap = p.aligned_by == AlignmentSource::kOverlap;
    f.exact = p.own_checkpoint && p.Aligned() && p.aligned_by == AlignmentSource::kContinuity;
    f.awaiting_confirmation = p.candidate.has_value();
    f.stale = p.stale;
    f.silent = p.Silent(now, options_.SilentAfterS());
    f.changed = p.changed;
    f.rendezvous_waiting = p.rendezvous.has_value();
    f.continuity_waiting = p.rendezvous.has_value() && p.continuity_prior;
    f.last_attempt = p.last_attempt;
    f.last_refine = p.last_refine;
    f.map_size = p.Map().size();
    f.own_size_at_attempt = p.own_size_at_attempt;
    f.map_size_at_attempt = p.peer_size_at_attempt;
    f.has_global = p.has_global;
    f.global_judged = p.relay_judged;
    f.global_newer = p.relay_judged_version != p.global_version;
    f.global_growth = static_cast<long>(p.global.size()) - static_cast<long>(p.relay_judged_size);
    f.last_judged = p.last_relay_judged;
    f.witness = p.direct && !p.direct->map.empty();
    f.carried = CarriedByLater(p);
    facts.push_back(f);
  }
  return facts;
}

std::vector<PeerReport> PeerBook::Reports(double now) const {
  std::vector<PeerReport> out;
  for (const auto& [key, p] : peers_) out.push_back(p.Report(now, options_.SilentAfterS()));
  return out;
}

std::vector<PeerBook::Received> PeerBook::ReceivedMaps() const {
  std::vector<Received> out;
  for (const auto& [key, p] : peers_) {
    if (p.own_checkpoint) continue;
    out.push_back({key, p.has_local ? &p.local : nullptr, p.has_global ? &p.global : nullptr});
  }
  return out;
}

std::vector<PeerBook::OwnEarlier> PeerBook::UnalignedOwnCheckpoints() const {
  std::vector<OwnEarlier> out;
  for (const auto& [key, p] : peers_) {
    if (p.own_checkpoint && !p.source) out.push_back({key.incarnation, p.origin_stamp, p.local, p.global});
  }
  return out;
}

std::vector<RobotId> PeerBook::AlignedRobots() const {
  std::set<RobotId> ids;
  for (const auto& [key, p] : peers_) {
    if (p.Aligned() && !p.own_checkpoint) ids.insert(key.robot);
  }
  return {ids.begin(), ids.end()};
}

std::vector<RobotId> PeerBook::StaleRobots() const {
  std::set<RobotId> ids;
  for (const auto& [key, p] : peers_) {
    if (p.stale && !p.own_checkpoint) ids.insert(key.robot);
  }
  return {ids.begin(), ids.end()};
}

}  // namespace mapmesh
