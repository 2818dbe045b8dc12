#include "agent/peer_schedule.h"

#include <algorithm>

namespace mapmesh {
namespace {

// A map of `size` landmarks has grown by retry_growth since it had `at_attempt`.
bool Grew(std::size_t size, std::size_t at_attempt, const ExchangeOptions& o) {
  return static_cast<double>(size) >=
         (1.0 + o.retry_growth) * static_cast<double>(std::max<std::size_t>(1, at_attempt));
}

// An unaligned peer's alignment is due: after align_period_s, when its map changed or ours grew
// by retry_growth. A peer that is silent (or can no longer speak) sends no better map: what it
// sent is tried whenever ours has changed, for the rest of the run.
bool AttemptDue(const PeerFacts& f, std::size_t own_size, double now, const ExchangeOptions& o) {
  if (now - f.last_attempt < o.align_period_s) return false;
  if (f.changed || Grew(own_size, f.own_size_at_attempt, o)) return true;
  return f.silent && own_size != f.own_size_at_attempt;
}

// An aligned peer's fresh alignment is due. A stale or silent peer's map will not change, but
// ours grows: an answer on the larger map may still correct where it is placed (a dead robot's
// map is a fact that stays, and is placed better as we learn more). An answer that
// disagreed with the transform in use waits for a second one to confirm it: that one is due as
// soon as either map changed, not only after the next fifth of growth (which may never come).
bool RealignDue(const PeerFacts& f, std::size_t own_size, double now, const ExchangeOptions& o) {
  if (!o.test_only.realign_on_growth || now - f.last_attempt < o.align_period_s) return false;
  if (f.awaiting_confirmation && (f.changed || own_size != f.own_size_at_attempt)) return true;
  return Grew(own_size, f.own_size_at_attempt, o) || Grew(f.map_size, f.map_size_at_attempt, o);
}

std::set<PeerKey> RelayTurns(const std::vector<PeerFacts>& facts, const ExchangeOptions& o) {
  if (!o.relay_global_maps) return {};
  std::vector<const PeerFacts*> due;
  for (const PeerFacts& f : facts) {
    if (f.aligned && !f.stale && f.has_global && (!f.global_judged || f.global_newer)) due.push_back(&f);
  }
  std::sort(due.begin(), due.end(), [](const PeerFacts* a, const PeerFacts* b) {
    if (a->global_judged != b->global_judged) return !a->global_judged;
    if (a->global_growth != b->global_growth) return a->global_growth > b->global_growth;
    if (a->last_judged != b->last_judged) return a->last_judged < b->last_judged;
    return a->key < b->key;
  });
  // Judging a relay compares it with every aligned peer's map (RelayPolicy::FirstConflict).
  const int witnesses = static_cast<int>(std::count_if(facts.begin(), facts.end(),
                                                       [](const PeerFacts& f) { return f.witness; }));
  const int limit = std::min(o.max_relay_checks_per_update,
                             std::max(1, o.max_relay_comparisons_per_update / std::max(1, witnesses)));
  std::set<PeerKey> turns;
  for (const PeerFacts* f : due) {
    if (static_cast<int>(turns.size()) >= limit) break;
    turns.insert(f->key);
  }
  return turns;
}

}  // namespace

int AlignmentBudget(const std::vector<PeerFacts>& facts, const ExchangeOptions& o) {
  if (o.peers_per_alignment <= 0) return o.max_alignments_per_update;
  const int peers = static_cast<int>(std::count_if(facts.begin(), facts.end(),
                                                   [](const PeerFacts& f) { return f.has_map && !f.exact; }));
  const int scaled = (peers + o.peers_per_alignment - 1) / o.peers_per_alignment;
  return std::min(limits::kMaxAlignmentsPerUpdate, std::max(o.max_alignments_per_update, scaled));
}

const char* ToString(TurnKind kind) {
  switch (kind) {
    case TurnKind::kRendezvous: return "rendezvous";
    case TurnKind::kAlign: return "align";
    case TurnKind::kRealign: return "realign";
    case TurnKind::kVerify: return "verify";
    case TurnKind::kRefine: return "refine";
  }
  return "?";
}

PeerSchedule PlanTurns(const std::vector<PeerFacts>& facts, std::size_t own_size, double now, const PeerKey& first_turn,
                       const ExchangeOptions& o) {
  PeerSchedule s;
  s.relay_turns = RelayTurns(facts, o);
  // Round robin: the first peer left without an alignment it was due last time goes first.
  std::vector<const PeerFacts*> order;
  const auto turn = std::lower_bound(facts.begin(), facts.end(), first_turn,
                                     [](const PeerFacts& f, const PeerKey& k) { return f.key < k; });
  for (auto it = turn; it != facts.end(); ++it) order.push_back(&*it);
  for (auto it = facts.begin(); it != turn; ++it) order.push_back(&*it);
  int budget = AlignmentBudget(facts, o);
  int rendezvous_budget = o.max_rendezvous_per_update;
  auto starve = [&](const PeerKey& key) {
    if (!s.next_turn) s.next_turn = key;
  };
  for (const PeerFacts* f : order) {
    if (!f->has_map) continue;
    const bool relay_turn = s.relay_turns.count(f->key) > 0;
    if (!f->aligned) {
      if (f->rendezvous_waiting && (o.ByRendezvous() || f->continuity_waiting)) {
        if (rendezvous_budget > 0) {
          --rendezvous_budget;
          s.turns.push_back({f->key, TurnKind::kRendezvous});
        } else {
          starve(f->key);  // its fit waits (a newer one replaces it)
        }
      }
      if (f->carried || !o.ByOverlap() || !AttemptDue(*f, own_size, now, o)) continue;
      if (budget <= 0) {
        starve(f->key);
        continue;
      }
      --budget;
      s.turns.push_back({f->key, TurnKind::kAlign, true});
      continue;
    }
    if (f->exact) continue;  // an earlier incarnation in our own frame
    // Aligned, and both maps grew since the last full alignment: align afresh. A transform
    // accepted on small maps can be a coincidence that verification at that same transform keeps
    // passing in a dense map; with more landmarks the true alignment has the larger support.
    if (o.ByOverlap() && RealignDue(*f, own_size, now, o)) {
      if (budget > 0) {
        --budget;
        // With no new map from the peer, or not its turn, the choice of its map stays.
        s.turns.push_back({f->key, TurnKind::kRealign, f->changed && relay_turn});
      } else {
        starve(f->key);
      }
    }
    if (f->stale) continue;
    if (f->changed || relay_turn) {
      s.turns.push_back({f->key, TurnKind::kVerify, relay_turn});
    } else if (o.refine_period_s > 0.0 && now - f->last_refine >= o.refine_period_s) {
      s.turns.push_back({f->key, TurnKind::kRefine});
    }
  }
  return s;
}

bool RelayedAlignmentDue(const RelayedAlignmentFacts& f, std::size_t size, std::size_t target, double now,
                         const ExchangeOptions& o) {
  if (!f.tried_at) return true;
  const double backoff = f.failures > 0 ? 2.0 : 1.0;
  const auto grown = [&](std::size_t n, std::size_t then) {
    return then == 0 || static_cast<double>(n) >= (1.0 + backoff * o.retry_growth) * static_cast<double>(then);
  };
  const bool confirm = f.candidate && now >= *f.tried_at + backoff * o.align_period_s;
  return confirm || grown(size, f.tried_size) || grown(target, f.tried_target);
}

}  // namespace mapmesh
