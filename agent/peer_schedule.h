#pragma once
// Which work an agent's map exchange does on its peers in one update, pure: a table of facts
// about each peer incarnation in, a list of turns out, modelled on the lockstep pacer (facts in,
// decisions out, time a parameter). MapExchange carries the turns out in order.
//
// The rules (docs/EXCHANGE.md "Bounded work"):
// - An unaligned peer with a rendezvous fit waiting has it weighed (a rendezvous turn); an
//   unaligned peer is aligned by overlap when an attempt is due (align_period_s since the last,
//   and its map changed or ours grew by retry_growth; a silent peer's whenever ours changed),
//   unless a later incarnation in its frame carries its map (then only that one is searched:
//   every search is a chance of a false answer, and a restart storm would multiply them).
// - An aligned live peer is aligned afresh when either map grew by retry_growth (a realign turn),
//   or sooner while a disagreeing answer awaits confirmation; then, when it sent a newer map or
//   its global map's turn as a relay came, its map is verified at the known transform (a verify
//   turn); otherwise its transform is refined on our map every refine_period_s (a refine turn).
//   A stale peer sends nothing more: its map is not verified or refined again, but it is still
//   aligned afresh as ours grows.
// - Rendezvous turns are budgeted too (max_rendezvous_per_update): a peer left without its turn
//   keeps its fit waiting, and the next update starts with it.
// - Full alignments (align and realign turns) are budgeted: max_alignments_per_update, or one
//   per peers_per_alignment peers with a map when that is more (AlignmentBudget), round robin
//   from the first peer left without one it was due. Relays (newer global maps) are
//   judged at most max_relay_checks_per_update, and fewer when judging them would compare more
//   than max_relay_comparisons_per_update maps: never judged first, then those that grew most,
//   then those judged longest ago.
// The turns of one peer are alternatives in order: the first that settles the peer (an
// accepted rendezvous, an accepted realignment) ends them.
// - A chain the joining back-end holds only through relays (fusion_backend.h) is aligned when it
//   was never tried, when its rebuilt map or the target grew by retry_growth since the last try,
//   or align_period_s after an accepted alignment that waits for a later one to agree; each try
//   in a row not accepted doubles both, once (RelayedAlignmentDue).

#include <cstddef>
#include <cstdint>
#include <optional>
#include <set>
#include <vector>

#include "agent/peer_state.h"
#include "common/options/exchange_options.h"

namespace mapmesh {

// What the schedule reads of one peer incarnation.
struct PeerFacts {
  PeerKey key;
  bool has_map = false;                // a local or global map of it arrived
  bool aligned = false;                // it contributes with a verified alignment
  bool aligned_by_overlap = false;     // ... accepted last from map overlap
  bool exact = false;                  // ... placed by continuity: its frame is ours, nothing to revisit
  bool awaiting_confirmation = false;  // an accepted answer waits for a second one to agree
  bool stale = false;                  // its writer is gone
  bool silent = false;                 // stale, an own checkpoint, or no map for silent_after_s
  bool changed = false;                // a map arrived since its last attempt or verification
  bool rendezvous_waiting = false;     // a rendezvous fit of its frame waits to be weighed ...
  bool continuity_waiting = false;     // ... or a transform of its frame known already (the same frame as an
                                       // aligned one's): weighed whatever align_by says
  bool carried = false;                // a later incarnation in its frame (the same stream, replayed) holds
                                       // at least as many landmarks: searching this one adds nothing
  double last_attempt = -1e300;        // its last full alignment
  double last_refine = -1e300;         // its last alignment, verification or refinement
  std::size_t map_size = 0;            // the map of it that is aligned
  std::size_t own_size_at_attempt = 0, map_size_at_attempt = 0;
  // Its global map as a relay (aligned, live peers only).
  bool has_global = false;
  bool global_judged = false;   // some global map of it was judged as a relay
  bool global_newer = false;    // a global map newer than the one judged arrived
  long global_growth = 0;       // landmarks its global map gained since the one judged
  double last_judged = -1e300;  // when its global map was last judged
  bool witness = false;         // its one-hop map is fused (a relay is compared with it)
};

enum class TurnKind { kRendezvous, kAlign, kRealign, kVerify, kRefine };
const char* ToString(TurnKind kind);

struct Turn {
  PeerKey key;
  TurnKind kind = TurnKind::kAlign;
  bool judge_relay = false;  // verify, realign: the peer's newer global map is judged as a relay
  bool operator==(const Turn&) const = default;
};

struct PeerSchedule {
  std::vector<Turn> turns;
  std::set<PeerKey> relay_turns;     // peers whose global map is judged in this update
  std::optional<PeerKey> next_turn;  // the first peer left without a full alignment it was due
};

// Full alignments per update: max_alignments_per_update, or one per peers_per_alignment peer
// incarnations with a map (but earlier incarnations of our own in our frame) when that is more.
int AlignmentBudget(const std::vector<PeerFacts>& facts, const ExchangeOptions& o);

// What the joining back-end knows of a relayed chain's alignments.
struct RelayedAlignmentFacts {
  std::optional<double> tried_at;                // when the last was tried (none: never)
  std::size_t tried_size = 0, tried_target = 0;  // the chain's rebuilt map's and the target's sizes then
  bool candidate = false;                        // an accepted one waits for a later one to agree
  int failures = 0;                              // tries in a row not accepted
};

// Whether a relayed chain is aligned at scenario time `now`, its rebuilt map holding `size`
// landmarks and the map it is aligned against `target`. Most relayed chains are of robots that
// map elsewhere: at 16 agents on park4, 1 try in 5 was accepted, and the tries were a quarter of
// joining's CPU; doubling the wait after a failed try halves them and places the same chains.
bool RelayedAlignmentDue(const RelayedAlignmentFacts& f, std::size_t size, std::size_t target, double now,
                         const ExchangeOptions& o);

// The turns of one update at scenario time `now`, our local map holding own_size landmarks;
// `facts` in key order; round robin from first_turn.
PeerSchedule PlanTurns(const std::vector<PeerFacts>& facts, std::size_t own_size, double now, const PeerKey& first_turn,
                       const ExchangeOptions& options);

}  // namespace mapmesh
