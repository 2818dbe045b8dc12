#include "agent/map_exchange.h"

#include <algorithm>
#include <set>

#include "common/check.h"
#include "common/metrics/chi2.h"

namespace mapmesh {
MapExchange::MapExchange(RobotId self, std::uint32_t incarnation, const ExchangeOptions& options, std::uint64_t seed)
    : self_(self),
      incarnation_(incarnation),
      options_(options),
      rng_(seed),
      fusion_(MakeFusionBackend(self, incarnation, options.global)),
      rendezvous_gate_(Chi2Quantile(options.rendezvous_gate_probability, 3)) {}

MapExchange::Receipt MapExchange::OnPeerMap(RobotId robot, std::uint32_t incarnation, MapKind kind,
                                            std::uint32_t version, double origin_stamp, LandmarkMap map, double now) {
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
  p.report.key = key;
  if (kind == MapKind::kLocal) {
    p.local_version = version;
    p.local_heard = now;
    p.local = std::move(map);
    p.has_local = true;
    p.report.local_landmarks = static_cast<int>(p.local.size());
  } else {
    p.global_version = version;
    p.global_heard = now;
    p.global = std::move(map);
    p.has_global = true;
    p.report.global_landmarks = static_cast<int>(p.global.size());
  }
  p.report.origin_stamp = origin_stamp;
  p.report.last_heard = now;
  p.changed = true;
  p.report.stale = false;  // heard again: it speaks for itself
  p.superseded_by.reset();
  p.report.superseded = false;
  return Receipt::kAccepted;
}

bool MapExchange::MakeRoomFor(RobotId robot, double now) {
  std::vector<PeerStates::iterator> kept;
  for (auto it = peers_.lower_bound({robot, 0}); it != peers_.end() && it->first.robot == robot; ++it)
    kept.push_back(it);
  if (static_cast<int>(kept.size()) < options_.max_incarnations) return true;
  // Evict the incarnation heard longest ago among those that never contributed and can no
  // longer speak; one that did contribute stays (nothing learned is lost).
  auto victim = peers_.end();
  for (auto it : kept) {
    const PeerState& p = it->second;
    if (p.report.ever_aligned || p.report.own_checkpoint || !Silent(p, now)) continue;
    if (victim == peers_.end() || p.report.last_heard < victim->second.report.last_heard) victim = it;
  }
  if (victim == peers_.end()) return false;
  peers_.erase(victim);
  return true;
}

void MapExchange::OnPeerLiveliness(RobotId robot, bool alive, double now) {
  for (auto& [key, p] : peers_) {
    if (key.robot != robot || p.report.own_checkpoint) continue;
    if (!alive && !p.report.stale) {
      p.report.stale = true;
      p.report.stale_since = now;
    } else if (alive) {
      p.report.stale = false;
    }
    p.report.frozen = p.Frozen();
    p.report.silent = Silent(p, now);
  }
}

void MapExchange::SetLive(const std::set<PeerKey>& live, double now) {
  for (auto& [key, p] : peers_) {
    if (p.report.own_checkpoint) continue;
    const bool alive = live.count(key) > 0;
    if (!alive && !p.report.stale) {
      p.report.stale = true;
      p.report.stale_since = now;
    } else if (alive) {
      p.report.stale = false;
    }
    p.report.frozen = p.Frozen();
    p.report.silent = Silent(p, now);
  }
}

void MapExchange::AddOwnCheckpoint(std::uint32_t incarnation, double origin_stamp, LandmarkMap local,
                                   LandmarkMap global) {
  PeerState& p = peers_[{self_, incarnation}];
  p.report.key = {self_, incarnation};
  p.report.own_checkpoint = true;
  p.report.stale = true;  // that process is gone; its maps stay
  p.report.origin_stamp = origin_stamp;
  p.local = std::move(local);
  p.global = std::move(global);
  p.has_local = true;
  p.has_global = !p.global.empty();
  p.report.local_landmarks = static_cast<int>(p.local.size());
  p.report.global_landmarks = static_cast<int>(p.global.size());
  p.changed = true;
}

void MapExchange::Drop(PeerState& p, double now) {
  ++p.report.drops;
  p.superseded_by.reset();
  p.report.superseded = false;
  p.report.aligned = false;
  p.report.dropped = true;
  p.source.reset();
  p.direct.reset();
  p.last_attempt = now;
}

bool MapExchange::Align(PeerState& p, const LandmarkMap& own_local, double now, bool reconsider_relay) {
  const LandmarkMap& theirs = p.Map();
  const AlignmentResult r = AlignMaps(own_local, theirs, options_.align, rng_);
  p.report.last_verdict = r.verdict;
  p.last_attempt = now;
  p.own_size_at_attempt = own_local.size();
  p.peer_size_at_attempt = theirs.size();
  p.changed = false;
  if (!r.accepted()) return false;
  const Eigen::Vector2d at = Centroid(theirs);
  if (std::any_of(p.refuted.begin(), p.refuted.end(),
                  [&](const Pose2& t) { return relay_.Agree(t, r.transform, at); })) {
    ++p.report.refuted_answers;
    return false;
  }
  // An answer is used once a second, later one agrees with it (or with the transform in use).
  const bool confirmed = !options_.test_only.confirm_alignments ||
                         (p.report.aligned && relay_.Agree(p.report.to_own, r.transform, at)) ||
                         (p.candidate && relay_.Agree(*p.candidate, r.transform, at));
  if (!confirmed) {
    p.candidate = r.transform;
    ++p.report.unconfirmed;
    return false;
  }
  p.candidate.reset();
  Use(p, r, own_local, reconsider_relay, now);
  return true;
}

void MapExchange::Use(PeerState& p, const AlignmentResult& r, const LandmarkMap& own_local, bool reconsider_relay,
                      double now) {
  p.report.to_own = r.transform;
  p.report.to_own_cov = r.cov;
  p.report.centroid = Centroid(p.Map());
  p.last_refine = now;
  ChooseSource(p, own_local, reconsider_relay, now);
}

bool MapExchange::Verify(PeerState& p, const LandmarkMap& own_local, double now, bool judge_relay) {
  const AlignmentResult r = VerifyAlignment(own_local, p.Map(), p.report.to_own, options_.align);
  p.report.last_verdict = r.verdict;
  p.changed = false;
  if (!r.accepted()) return false;
  Use(p, r, own_local, judge_relay, now);
  return true;
}

void MapExchange::OnRendezvous(const PeerKey& key, const RendezvousFit& fit) {
  if (!options_.ByRendezvous() || !fit.accepted()) return;
  const auto it = peers_.find(key);
  if (it == peers_.end() || it->second.report.own_checkpoint) return;
  AlignmentResult r;
  r.verdict = AlignmentVerdict::kAccepted;
  r.transform = fit.transform;
  r.cov = fit.cov;
  it->second.rendezvous = r;
  ++it->second.report.rendezvous_fits;
}

bool MapExchange::AlignByRendezvous(PeerState& p, const LandmarkMap& own_local, double now) {
  const AlignmentResult fit = *p.rendezvous;
  p.rendezvous.reset();
  const LandmarkMap& theirs = p.Map();
  const Eigen::Vector2d at = Centroid(theirs);
  // Verified like an overlap answer, at the fit: the maps laid over each other there must match
  // (guided matching, the residual and overlap tests). The maps' own fit at it is the answer,
  // and the two independent kinds of evidence agreeing confirm it. Sightings alone never
  // suffice: a peer that reports every pose shifted by the same error is consistent with
  // itself, and only its map can give it away.
  AlignmentOptions guided = options_.align;
  guided.min_inliers = options_.rendezvous_min_inliers;
  // Sightings place a peer to decimetres and degrees (MRCLAM: 0.05-0.7 m, 1-14 deg), wider than
  // the landmark gates: the guided matching allows for the fit's covariance.
  const AlignmentResult v = VerifyUncertainAlignment(own_local, theirs, fit.transform, fit.cov, guided);
  if (!v.accepted() || TransformDistance2(v.transform, v.cov, fit.transform, fit.cov) > rendezvous_gate_) {
    const bool unjudged = v.covered < guided.min_inliers;
    ++(unjudged ? p.report.rendezvous_unjudged : p.report.rendezvous_refused);
    return false;
  }
  if (std::any_of(p.refuted.begin(), p.refuted.end(),
                  [&](const Pose2& t) { return relay_.Agree(t, v.transform, at); })) {
    ++p.report.refuted_answers;
    return false;
  }
  ++p.report.rendezvous_confirmed;
  p.candidate.reset();
  Use(p, v, own_local, /*reconsider_relay=*/true, now);
  return true;
}

void MapExchange::MarkAligned(PeerState& p, AlignmentSource by, double now) {
  p.report.aligned = true;
  p.report.dropped = false;
  p.report.failures = 0;
  p.report.aligned_by = by;
  if (!p.report.ever_aligned) {
    p.report.aligned_since = now;
    p.report.first_aligned_by = by;
  }
  p.report.ever_aligned = true;
}

void MapExchange::Refine(PeerState& p, const LandmarkMap& own_local, double now) {
  p.last_refine = now;
  const AlignmentResult r = VerifyAlignment(own_local, p.Map(), p.report.to_own, options_.align);
  if (!r.accepted() || !relay_.Agree(r.transform, p.report.to_own, Centroid(p.Map()))) return;
  ++p.report.refinements;
  Use(p, r, own_local, /*reconsider_relay=*/false, now);
}

bool MapExchange::RefuteByRelay(const PeerState& p, const Pose2& to_own, PeerState& q, const LandmarkMap& own_local,
                                double now) {
  if (!options_.test_only.refute_by_relay || !q.report.aligned) return false;  // q.direct is set: FirstConflict
  // At most once per align period for each relay: one that does not hold q's map must not keep
  // another, which does, from being heard.
  const auto checked = q.last_refute_check.find(p.report.key);
  if (checked != q.last_refute_check.end() && now - checked->second < options_.align_period_s) return false;
  q.last_refute_check[p.report.key] = now;
  const std::optional<AlignmentResult> placed = relay_.Refutation(peers_, p, to_own, q, own_local, rng_);
  if (!placed) return false;
  q.refuted.push_back(q.report.to_own);
  ++q.report.refuted;
  q.report.refuted_by = p.report.key.robot;
  q.candidate.reset();
  if (q.report.frozen) {
    // A frozen q cannot speak for itself any more: its landmarks stay, moved to where the live
    // relay (holding them) places them; while that relay is used it brings them, and q's own
    // copy stays out (see Update).
    ++q.report.replaced;
    q.superseded_by = p.report.key;
    Use(q, *placed, own_local, /*reconsider_relay=*/false, now);
    return true;
  }
  q.report.relayed = false;
  Drop(q, now);
  return true;
}

void MapExchange::ChooseSource(PeerState& p, const LandmarkMap& own_local, bool reconsider_relay, double now) {
  MapSource s;
  s.robot = p.report.key.robot;
  s.incarnation = p.report.key.incarnation;
  s.to_own = p.report.to_own;
  s.to_own_cov = p.report.to_own_cov;
  s.map = p.Map();
  p.direct = s;
  // The peer's global map is in the peer's frame too: use it if it verifies where the peer's
  // local map aligned. Without reconsider_relay the earlier choice stays, at the new transform.
  if (reconsider_relay) {
    p.relay_judged = true;
    p.relay_judged_version = p.global_version;
    p.relay_judged_size = p.global.size();
    p.last_relay_judged = now;
    ++p.report.relays_judged;
    p.report.relayed = false;
    if (options_.relay_global_maps && p.has_global && p.global.size() > s.map.size()) {
      const AlignmentResult g = VerifyAlignment(own_local, p.global, s.to_own, options_.align);
      if (g.accepted() && relay_.Agree(g.transform, s.to_own, Centroid(p.global))) {
        const std::optional<PeerKey> conflict = options_.test_only.relay_must_agree
                                                    ? relay_.FirstConflict(peers_, p, s.to_own)
                                                    : std::nullopt;
        if (!conflict) {
          p.report.relayed = true;
        } else if (RefuteByRelay(p, s.to_own, peers_.at(*conflict), own_local, now)) {
          // Our alignment of the other peer was the false one; the relay may now agree.
          refuted_ = true;
          p.report.relayed = !relay_.FirstConflict(peers_, p, s.to_own);
          if (!p.report.relayed) ++p.report.relay_conflicts;
        } else {
          ++p.report.relay_conflicts;
        }
      }
    }
  }
  // A relay not judged again keeps the global map judged last (moved by the new transform).
  if (p.report.relayed) s.map = reconsider_relay || !p.source ? p.global : p.source->map;
  // An earlier own incarnation's global map is frozen (it cannot echo anything back).
  if (p.report.own_checkpoint) p.direct = s;
  p.source = std::move(s);
}

std::vector<PeerFacts> MapExchange::Facts(double now) const {
  std::vector<PeerFacts> facts;
  facts.reserve(peers_.size());
  for (const auto& [key, p] : peers_) {
    PeerFacts f;
    f.key = key;
    f.has_map = p.has_local || p.has_global;
    f.aligned = p.report.aligned;
    f.aligned_by_overlap = p.report.aligned_by == AlignmentSource::kOverlap;
    f.awaiting_confirmation = p.candidate.has_value();
    f.stale = p.report.stale;
    f.silent = Silent(p, now);
    f.changed = p.changed;
    f.rendezvous_waiting = p.rendezvous.has_value();
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
    facts.push_back(f);
  }
  return facts;
}

bool MapExchange::Take(const Turn& turn, const LandmarkMap& own_local, double now, Round& round) {
  PeerState& p = peers_.at(turn.key);
  switch (turn.kind) {
    case TurnKind::kRendezvous:
      if (!AlignByRendezvous(p, own_local, now)) return false;
      round.chosen.insert(turn.key);
      MarkAligned(p, AlignmentSource::kRendezvous, now);
      round.changed = true;
      return true;
    case TurnKind::kAlign:
      ++p.report.attempts;
      if (!Align(p, own_local, now, /*reconsider_relay=*/true)) return false;
      round.chosen.insert(turn.key);
      MarkAligned(p, AlignmentSource::kOverlap, now);
      round.changed = true;
      return true;
    case TurnKind::kRealign: {
      // An accepted answer replaces the transform; otherwise verification goes on.
      const Pose2 before = p.report.to_own;
      const Eigen::Vector2d at = p.report.centroid;
      const bool was_changed = p.changed;
      ++p.report.realignments;
      if (!Align(p, own_local, now, turn.judge_relay)) {
        p.changed = was_changed;
        return false;
      }
      if (turn.judge_relay) round.chosen.insert(turn.key);
      p.report.failures = 0;
      p.report.aligned_by = AlignmentSource::kOverlap;
      if (!relay_.Agree(p.report.to_own, before, at)) {
        ++p.report.corrections;
        round.changed = true;
      }
      return true;
    }
    case TurnKind::kVerify:
      // Every newer map of an aligned peer is verified at the known transform before it is used.
      ++p.report.verifications;
      if (Verify(p, own_local, now, turn.judge_relay)) {
        if (turn.judge_relay) round.chosen.insert(turn.key);
        p.report.failures = 0;
        return false;
      }
      ++p.report.rejected;
      if (++p.report.failures >= options_.drop_after_failures) {
        Drop(p, now);
        round.changed = true;
      }
      return false;
    case TurnKind::kRefine: Refine(p, own_local, now); return false;
  }
  return false;
}

bool MapExchange::Update(const LandmarkMap& own_local, double now) {
  ++updates_;
  refuted_ = false;
  for (auto& [key, p] : peers_) {
    p.report.frozen = p.Frozen();
    p.report.silent = Silent(p, now);
    // Aligned by overlap: later rendezvous fits add nothing (verification refines the transform).
    if (p.report.aligned && p.report.aligned_by == AlignmentSource::kOverlap) p.rendezvous.reset();
  }
  const PeerSchedule schedule = PlanTurns(Facts(now), own_local.size(), now, next_turn_, options_);
  if (schedule.next_turn) next_turn_ = *schedule.next_turn;
  Round round;
  std::optional<PeerKey> settled;  // a peer's turns are alternatives: the first that settles it ends them
  for (const Turn& turn : schedule.turns) {
    if (settled == turn.key) continue;
    if (Take(turn, own_local, now, round)) settled = turn.key;
  }
  // A new or moved alignment changes what the other peers' relays must agree with: the peers
  // whose maps were chosen in this round choose again, now that all its transforms are known.
  // (A peer that sent nothing new keeps its choice: until its liveliness is lost, a dead peer
  // is not known to be dead, and what it gave must stay as it was.)
  const bool changed = round.changed || refuted_;
  if (changed && options_.test_only.relay_must_agree) {
    for (auto& [key, p] : peers_) {
      if (p.source && round.chosen.count(key)) ChooseSource(p, own_local, true, now);
    }
  }
  Build(own_local);
  return changed;
}

void MapExchange::Build(const LandmarkMap& own_local) {
  std::vector<MapSource> sources, direct;
  for (auto& [key, p] : peers_) {
    if (p.direct) direct.push_back(*p.direct);
    if (!p.source) continue;
    // A frozen peer re-placed by a relay: while that relay is used, it brings the same
    // landmarks placed the same way; two copies of a bent map would not coincide. When the
    // relay is not used, the peer's own copy is (nothing learned is lost).
    if (p.superseded_by && p.report.aligned) {
      const auto relay = peers_.find(*p.superseded_by);
      p.report.superseded = relay != peers_.end() && relay->second.source && relay->second.report.relayed;
      if (p.report.superseded) continue;
    }
    sources.push_back(*p.source);
  }
  FusionBackend::Built built = fusion_->Build(own_local, sources, direct);
  global_ = std::move(built.global);
  published_ = std::move(built.published);
}

std::vector<PeerReport> MapExchange::Peers() const {
  std::vector<PeerReport> out;
  for (const auto& [key, p] : peers_) out.push_back(p.report);
  return out;
}

std::vector<MapExchange::Received> MapExchange::ReceivedMaps() const {
  std::vector<Received> out;
  for (const auto& [key, p] : peers_) {
    if (p.report.own_checkpoint) continue;
    out.push_back({key, p.has_local ? &p.local : nullptr, p.has_global ? &p.global : nullptr});
  }
  return out;
}

std::vector<MapExchange::OwnEarlier> MapExchange::UnalignedOwnCheckpoints() const {
  std::vector<OwnEarlier> out;
  for (const auto& [key, p] : peers_) {
    if (p.report.own_checkpoint && !p.source)
      out.push_back({key.incarnation, p.report.origin_stamp, p.local, p.global});
  }
  return out;
}

std::vector<RobotId> MapExchange::AlignedRobots() const {
  std::set<RobotId> ids;
  for (const auto& [key, p] : peers_) {
    if (p.report.aligned && !p.report.own_checkpoint) ids.insert(key.robot);
  }
  return {ids.begin(), ids.end()};
}

std::vector<RobotId> MapExchange::StaleRobots() const {
  std::set<RobotId> ids;
  for (const auto& [key, p] : peers_) {
    if (p.report.stale && !p.report.own_checkpoint) ids.insert(key.robot);
  }
  return {ids.begin(), ids.end()};
}

}  // namespace mapmesh
