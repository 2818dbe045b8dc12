#include "agent/map_exchange.h"

#include <algorithm>
#include <set>
#include <utility>

#include "common/check.h"
#include "common/solver/chi2.h"

namespace mapmesh {
MapExchange::MapExchange(RobotId self, std::uint32_t incarnation, const ExchangeOptions& options, std::uint64_t seed)
    : self_(self),
      incarnation_(incarnation),
      options_(options),
      rng_(seed),
      fusion_(MakeFusionBackend(self, incarnation, options, seed ^ 0x6a09e667f3bcc909ULL)),
      rendezvous_gate_(Chi2Quantile(options.rendezvous_gate_probability, 3)) {}

void MapExchange::Drop(PeerState& p, double now) {
  ++p.counters.drops;
  p.superseded_by.reset();
  p.stage = PeerStage::kDropped;
  p.source.reset();
  p.direct.reset();
  p.last_attempt = now;
}

bool MapExchange::Align(PeerState& p, const LandmarkMap& own_local, double now, bool reconsider_relay) {
  const LandmarkMap& theirs = p.Map();
  const AlignmentResult r = AlignMaps(own_local, theirs, options_.align, rng_);
  p.last_verdict = r.verdict;
  p.last_attempt = now;
  p.own_size_at_attempt = own_local.size();
  p.peer_size_at_attempt = theirs.size();
  p.changed = false;
  if (!r.accepted()) return false;
  const Eigen::Vector2d at = Centroid(theirs);
  if (std::any_of(p.refuted.begin(), p.refuted.end(),
                  [&](const Pose2& t) { return relay_.Agree(t, r.transform, at); })) {
    ++p.counters.refuted_answers;
    return false;
  }
  // An answer is used once a second, later one agrees with it (or with the transform in use),
  // and the second must rest on a landmark pair the first did not: the same pairs again are the
  // same evidence again. A false match that the maps' shapes allow comes back on every attempt as
  // reliably as a true one (a survivor of a restart storm confirmed a false 92 degrees from 6
  // pairs found twice on a dead peer's frozen map).
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  pairs.reserve(r.inliers.size());
  for (const auto& [i, j] : r.inliers) pairs.emplace_back(own_local.landmarks[i].id, theirs.landmarks[j].id);
  std::sort(pairs.begin(), pairs.end());
  const bool agrees_in_use = p.Aligned() && relay_.Agree(p.to_own, r.transform, at);
  if (p.Aligned() && !agrees_in_use) {
    // A correction must be better supported than what it corrects: the transform in use,
    // verified on the same maps, keeps its place when as many pairs hold there.
    const AlignmentResult held = VerifyAlignment(own_local, theirs, p.to_own, options_.align);
    if (held.accepted() && held.inliers.size() >= r.inliers.size()) {
      ++p.counters.outsupported;
      return false;
    }
  }
  const bool agrees_candidate = p.candidate && relay_.Agree(*p.candidate, r.transform, at);
  const bool new_evidence = !std::includes(p.candidate_pairs.begin(), p.candidate_pairs.end(), pairs.begin(),
                                           pairs.end());
  const bool confirmed = !options_.test_only.confirm_alignments || agrees_in_use || (agrees_candidate && new_evidence);
  if (!confirmed) {
    ++p.counters.unconfirmed;
    if (agrees_candidate) return false;  // the candidate stands, on its own evidence
    p.candidate = r.transform;
    p.candidate_pairs = std::move(pairs);
    if (!p.Aligned()) p.stage = PeerStage::kCandidate;
    return false;
  }
  p.candidate.reset();
  p.candidate_pairs.clear();
  Use(p, r, own_local, reconsider_relay, now);
  return true;
}

void MapExchange::Use(PeerState& p, const AlignmentResult& r, const LandmarkMap& own_local, bool reconsider_relay,
                      double now) {
  p.to_own = r.transform;
  p.to_own_cov = r.cov;
  p.centroid = Centroid(p.Map());
  p.last_refine = now;
  ChooseSource(p, own_local, reconsider_relay, now);
}

bool MapExchange::Verify(PeerState& p, const LandmarkMap& own_local, double now, bool judge_relay) {
  const AlignmentResult r = VerifyAlignment(own_local, p.Map(), p.to_own, options_.align);
  p.last_verdict = r.verdict;
  p.changed = false;
  if (!r.accepted()) return false;
  Use(p, r, own_local, judge_relay, now);
  return true;
}

void MapExchange::OnRendezvous(const PeerKey& key, const RendezvousFit& fit) {
  if (!options_.ByRendezvous() || !fit.accepted()) return;
  const auto it = book_.states().find(key);
  if (it == book_.states().end() || it->second.own_checkpoint) return;
  AlignmentResult r;
  r.verdict = AlignmentVerdict::kAccepted;
  r.transform = fit.transform;
  r.cov = fit.cov;
  it->second.rendezvous = r;
  it->second.continuity_prior = false;  // a fit of the sightings replaces a prior it was waiting on
  ++it->second.counters.rendezvous_fits;
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
    ++(unjudged ? p.counters.rendezvous_unjudged : p.counters.rendezvous_refused);
    return false;
  }
  if (std::any_of(p.refuted.begin(), p.refuted.end(),
                  [&](const Pose2& t) { return relay_.Agree(t, v.transform, at); })) {
    ++p.counters.refuted_answers;
    return false;
  }
  ++p.counters.rendezvous_confirmed;
  p.candidate.reset();
  p.candidate_pairs.clear();
  Use(p, v, own_local, /*reconsider_relay=*/true, now);
  return true;
}

void MapExchange::MarkAligned(PeerState& p, AlignmentSource by, double now) {
  p.stage = PeerStage::kAligned;
  p.failures = 0;
  p.aligned_by = by;
  if (!p.ever_aligned) {
    p.aligned_since = now;
    p.first_aligned_by = by;
  }
  p.ever_aligned = true;
}

void MapExchange::Refine(PeerState& p, const LandmarkMap& own_local, double now) {
  p.last_refine = now;
  const AlignmentResult r = VerifyAlignment(own_local, p.Map(), p.to_own, options_.align);
  if (!r.accepted() || !relay_.Agree(r.transform, p.to_own, Centroid(p.Map()))) return;
  ++p.counters.refinements;
  Use(p, r, own_local, /*reconsider_relay=*/false, now);
}

bool MapExchange::RefuteByRelay(const PeerState& p, const Pose2& to_own, PeerState& q, const LandmarkMap& own_local,
                                double now) {
  if (!options_.test_only.refute_by_relay || !q.Aligned()) return false;  // q.direct is set: FirstConflict
  // At most once per align period for each relay: one that does not hold q's map must not keep
  // another, which does, from being heard.
  const auto checked = q.last_refute_check.find(p.key);
  if (checked != q.last_refute_check.end() && now - checked->second < options_.align_period_s) return false;
  q.last_refute_check[p.key] = now;
  const std::optional<AlignmentResult> placed = relay_.Refutation(book_.states(), p, to_own, q, own_local, rng_);
  if (!placed) return false;
  q.refuted.push_back(q.to_own);
  ++q.counters.refuted;
  q.refuted_by = p.key.robot;
  q.candidate.reset();
  q.candidate_pairs.clear();
  if (q.Frozen()) {
    // A frozen q cannot speak for itself any more: its landmarks stay, moved to where the live
    // relay (holding them) places them; while that relay is used it brings them, and q's own
    // copy stays out (see Update).
    ++q.counters.replaced;
    q.superseded_by = p.key;
    Use(q, *placed, own_local, /*reconsider_relay=*/false, now);
    return true;
  }
  q.relayed = false;
  Drop(q, now);
  return true;
}

void MapExchange::ChooseSource(PeerState& p, const LandmarkMap& own_local, bool reconsider_relay, double now) {
  MapSource s;
  s.robot = p.key.robot;
  s.incarnation = p.key.incarnation;
  s.to_own = p.to_own;
  s.to_own_cov = p.to_own_cov;
  s.map = p.Map();
  p.direct = s;
  // The peer's global map is in the peer's frame too: use it if it verifies where the peer's
  // local map aligned. Without reconsider_relay the earlier choice stays, at the new transform.
  if (reconsider_relay) {
    p.relay_judged = true;
    p.relay_judged_version = p.global_version;
    p.relay_judged_size = p.global.size();
    p.last_relay_judged = now;
    ++p.counters.relays_judged;
    p.relayed = false;
    if (p.own_checkpoint && p.aligned_by == AlignmentSource::kContinuity) {
      // An earlier incarnation of ours in our own frame: its global map (what it had fused of
      // others) is in our frame exactly, nothing to verify. It is placed when our frame is
      // fixed, before our map holds anything it could be verified on; verifying it there lost
      // every peer's landmarks at each restart (a restart storm's agent ended with its own map).
      // It is used even when smaller than its local map (written while that one grew faster):
      // what its local map held, ours rebuilds from the same stream; what it fused of others
      // it alone still holds.
      p.relayed = p.has_global && !p.global.empty();
    } else if (options_.relay_global_maps && p.has_global && p.global.size() > s.map.size()) {
      const AlignmentResult g = VerifyAlignment(own_local, p.global, s.to_own, options_.align);
      if (g.accepted() && relay_.Agree(g.transform, s.to_own, Centroid(p.global))) {
        const std::optional<PeerKey> conflict = options_.test_only.relay_must_agree
                                                    ? relay_.FirstConflict(book_.states(), p, s.to_own)
                                                    : std::nullopt;
        if (!conflict) {
          p.relayed = true;
        } else if (RefuteByRelay(p, s.to_own, book_.states().at(*conflict), own_local, now)) {
          // Our alignment of the other peer was the false one; the relay may now agree.
          refuted_ = true;
          p.relayed = !relay_.FirstConflict(book_.states(), p, s.to_own);
          if (!p.relayed) ++p.counters.relay_conflicts;
        } else {
          ++p.counters.relay_conflicts;
        }
      }
    }
  }
  // A relay not judged again keeps the global map judged last (moved by the new transform).
  if (p.relayed) {
    s.map = reconsider_relay || !p.source ? p.global : p.source->map;
    s.relayed = true;
  }
  // An earlier own incarnation's global map is frozen (it cannot echo anything back).
  if (p.own_checkpoint) p.direct = s;
  p.source = std::move(s);
}

bool MapExchange::Take(const Turn& turn, const LandmarkMap& own_local, double now, Round& round) {
  PeerState& p = book_.states().at(turn.key);
  switch (turn.kind) {
    case TurnKind::kRendezvous: {
      const bool continuity = std::exchange(p.continuity_prior, false);
      if (!AlignByRendezvous(p, own_local, now)) return false;
      round.chosen.insert(turn.key);
      MarkAligned(p, continuity ? AlignmentSource::kContinuity : AlignmentSource::kRendezvous, now);
      round.changed = true;
      return true;
    }
    case TurnKind::kAlign:
      ++p.counters.attempts;
      if (!Align(p, own_local, now, /*reconsider_relay=*/true)) return false;
      round.chosen.insert(turn.key);
      MarkAligned(p, AlignmentSource::kOverlap, now);
      round.changed = true;
      return true;
    case TurnKind::kRealign: {
      // An accepted answer replaces the transform; otherwise verification goes on.
      const Pose2 before = p.to_own;
      const Eigen::Vector2d at = p.centroid;
      const bool was_changed = p.changed;
      ++p.counters.realignments;
      if (!Align(p, own_local, now, turn.judge_relay)) {
        p.changed = was_changed;
        return false;
      }
      if (turn.judge_relay) round.chosen.insert(turn.key);
      p.failures = 0;
      p.aligned_by = AlignmentSource::kOverlap;
      if (!relay_.Agree(p.to_own, before, at)) {
        ++p.counters.corrections;
        round.changed = true;
      }
      return true;
    }
    case TurnKind::kVerify:
      // Every newer map of an aligned peer is verified at the known transform before it is used.
      ++p.counters.verifications;
      if (Verify(p, own_local, now, turn.judge_relay)) {
        if (turn.judge_relay) round.chosen.insert(turn.key);
        p.failures = 0;
        return false;
      }
      ++p.counters.rejected;
      if (++p.failures >= options_.drop_after_failures) {
        Drop(p, now);
        round.changed = true;
      }
      return false;
    case TurnKind::kRefine: Refine(p, own_local, now); return false;
  }
  return false;
}

int MapExchange::PlaceOwnCheckpointsAt(double origin_stamp, const LandmarkMap& own_local, double now) {
  int placed = 0;
  for (auto& [key, p] : book_.states()) {
    if (!p.own_checkpoint || p.Aligned() || p.origin_stamp != origin_stamp) continue;
    AlignmentResult same;
    same.verdict = AlignmentVerdict::kAccepted;  // the identity, exactly (cov zero)
    MarkAligned(p, AlignmentSource::kContinuity, now);
    Use(p, same, own_local, /*reconsider_relay=*/true, now);
    ++placed;
  }
  // Into the global map at once: a checkpoint written before the next update carries the
  // global map as its record of them (they are no longer unaligned).
  if (placed > 0) Build(own_local);
  book_.UseCarriedIn(origin_stamp);
  return placed;
}

bool MapExchange::Update(const LandmarkMap& own_local, double now) {
  ++updates_;
  now_ = now;
  refuted_ = false;
  for (auto& [key, p] : book_.states()) {
    // Aligned by overlap: later rendezvous fits add nothing (verification refines the transform).
    if (p.Aligned() && p.aligned_by == AlignmentSource::kOverlap) p.rendezvous.reset();
  }
  const PeerSchedule schedule = PlanTurns(book_.Facts(now), own_local.size(), now, next_turn_, options_);
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
    for (auto& [key, p] : book_.states()) {
      if (p.source && round.chosen.count(key)) ChooseSource(p, own_local, true, now);
    }
  }
  Build(own_local);
  return changed;
}

void MapExchange::Build(const LandmarkMap& own_local) {
  std::vector<MapSource> sources, direct;
  for (auto& [key, p] : book_.states()) {
    if (p.direct) direct.push_back(*p.direct);
    if (!p.source) continue;
    // A frozen peer re-placed by a relay: while that relay is used, it brings the same
    // landmarks placed the same way; two copies of a bent map would not coincide. When the
    // relay is not used, the peer's own copy is (nothing learned is lost).
    if (p.superseded_by && p.Aligned()) {
      const auto relay = book_.states().find(*p.superseded_by);
      const bool used = relay != book_.states().end() && relay->second.source && relay->second.relayed;
      p.stage = used ? PeerStage::kSuperseded : PeerStage::kAligned;
      if (used) continue;
    }
    sources.push_back(*p.source);
  }
  SubmapInputs inputs = submap_inputs_;
  inputs.now = now_;
  FusionBackend::Built built = fusion_->Build(own_local, sources, direct, inputs);
  global_ = std::move(built.global);
  published_ = std::move(built.published);
  joining_ = built.joining;
  piecewise_ = built.piecewise;
  placements_ = std::move(built.placements);
}

}  // namespace mapmesh
