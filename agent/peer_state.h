#pragma once
// What an agent keeps of one peer incarnation (PeerState: its stage, the maps received and their
// versions, the alignment in use and its bookkeeping, and counters), and the view of it that
// status, stats and tests see (PeerReport). Plain data, shared by MapExchange and its
// RelayPolicy.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/merge/global_map.h"
#include "common/merge/map_alignment.h"
#include "common/types/messages.h"

namespace mapmesh {

// A peer's map frame: one incarnation of one robot.
struct PeerKey {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  auto operator<=>(const PeerKey&) const = default;
};

// Which kind of evidence an alignment came from.
// kContinuity: an earlier incarnation of this agent whose session began where this one's did
// (the feeder replayed the robot's stream from the start): its frame is ours. For a peer: a later
// incarnation placed where its earlier one was (same session start), verified on the maps.
enum class AlignmentSource : std::uint8_t { kNone = 0, kOverlap, kRendezvous, kContinuity };
inline const char* ToString(AlignmentSource s) {
  switch (s) {
    case AlignmentSource::kOverlap: return "overlap";
    case AlignmentSource::kRendezvous: return "rendezvous";
    case AlignmentSource::kContinuity: return "continuity";
    case AlignmentSource::kNone: break;
  }
  return "none";
}

// Where a peer incarnation stands in the exchange. Its transitions (MapExchange):
// unaligned -> candidate (an answer awaits a second, agreeing one) -> aligned (a verified
// alignment: the peer contributes); aligned -> dropped (verification kept failing, or a relay
// refuted it) -> candidate or aligned again; aligned <-> superseded (a frozen peer re-placed
// by a relay that, used now, brings its landmarks: its own copy is left out).
enum class PeerStage : std::uint8_t { kUnaligned = 0, kCandidate, kAligned, kSuperseded, kDropped };
const char* ToString(PeerStage stage);

// What the exchange counted of one peer incarnation: counters only, never read in a decision.
struct PeerCounters {
  int relays_judged = 0;    // times a global map of it was judged as a relay (max_relay_checks_per_update)
  int relay_conflicts = 0;  // times its global map disagreed with another peer's map (not relayed then)
  int refuted = 0;          // times our alignment of it lost to a relay's placement (then dropped, or re-placed
                            // when frozen) ...
  int replaced = 0;         // ... of which it was frozen and moved to the relay's placement
  int refuted_answers = 0;  // alignments refused for agreeing with a refuted one
  int attempts = 0, verifications = 0;
  int unconfirmed = 0;           // accepted alignments not (yet) confirmed by a later one on new pairs
  int outsupported = 0;          // answers refused: the transform in use holds as many pairs on the same maps
  int rejected = 0;              // failed verifications in all
  int drops = 0;                 // times the alignment was dropped
  int realignments = 0;          // fresh alignments of an aligned peer (realign_on_growth) ...
  int corrections = 0;           // ... that replaced a transform they disagreed with
  int refinements = 0;           // transforms refined on our newer own map alone (refine_period_s)
  int rendezvous_fits = 0;       // rendezvous fits of this frame that the sightings accepted ...
  int rendezvous_refused = 0;    // ... that the maps contradicted (laid over each other there, they did not match)
  int rendezvous_unjudged = 0;   // ... not used: the maps overlapped too little there to tell
  int rendezvous_confirmed = 0;  // ... that the maps confirmed: used
};

// What the agent knows about one peer incarnation, for status, stats and tests: a view made
// from its state on request (MapExchange::Peers), never kept.
struct PeerReport : PeerCounters {
  PeerKey key;
  PeerStage stage = PeerStage::kUnaligned;
  bool own_checkpoint = false;  // an earlier incarnation of this agent
  double origin_stamp = 0.0;    // when the peer's frame was fixed
  int local_landmarks = 0, global_landmarks = 0;
  bool aligned = false;  // currently contributes with a verified alignment (aligned or superseded)
  bool ever_aligned = false;
  bool dropped = false;  // was aligned, is not now
  bool stale = false;    // its writer is gone (liveliness)
  double stale_since = 0.0;
  bool frozen = false;         // can no longer speak (stale, or an own checkpoint): kept as it is
  bool silent = false;         // frozen, or no map for silent_after_s
  double last_heard = 0.0;     // scenario time of its last map (ours, when it arrived)
  double aligned_since = 0.0;  // scenario time of the first acceptance
  Pose2 to_own;                // the peer's frame in ours
  Eigen::Matrix3d to_own_cov = Eigen::Matrix3d::Zero();
  bool relayed = false;     // its global map is fused (not its local map)
  bool superseded = false;  // frozen and re-placed by a relay, which brings its landmarks now
  RobotId refuted_by = 0;   // the relay that refuted our alignment of it last
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  // of the peer map aligned last, in its frame
  int failures = 0;                                    // consecutive failed verifications (reset by a success)
  AlignmentVerdict last_verdict = AlignmentVerdict::kTooFewLandmarks;
  AlignmentSource aligned_by = AlignmentSource::kNone;  // of the alignment accepted last (verification keeps it)
  AlignmentSource first_aligned_by = AlignmentSource::kNone;
};

struct PeerState {
  PeerKey key;
  PeerStage stage = PeerStage::kUnaligned;
  PeerCounters counters;
  bool own_checkpoint = false;  // an earlier incarnation of this agent (its process is gone; its maps stay)
  bool stale = false;           // its writer is gone (liveliness, or not in a lockstep tick's list)
  double stale_since = 0.0;
  double origin_stamp = 0.0;  // when the peer's frame was fixed
  double last_heard = 0.0;    // when its last map arrived
  LandmarkMap local, global;
  bool has_local = false, has_global = false;
  std::uint32_t local_version = 0, global_version = 0;
  double local_heard = 0.0, global_heard = 0.0;  // when the last map of each kind arrived
  bool changed = false;                          // a map arrived since the last attempt or verification
  double last_attempt = -1e300;
  double last_refine = -1e300;  // last alignment, verification or refinement against our map
  std::size_t own_size_at_attempt = 0, peer_size_at_attempt = 0;
  AlignmentVerdict last_verdict = AlignmentVerdict::kTooFewLandmarks;
  int failures = 0;  // consecutive failed verifications (drop_after_failures)
  // The alignment in use (aligned or superseded): the peer's frame in ours, where the map was.
  Pose2 to_own;
  Eigen::Matrix3d to_own_cov = Eigen::Matrix3d::Zero();
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();   // of the peer map aligned last, in its frame
  AlignmentSource aligned_by = AlignmentSource::kNone;  // of the alignment accepted last (verification keeps it)
  AlignmentSource first_aligned_by = AlignmentSource::kNone;
  bool ever_aligned = false;
  double aligned_since = 0.0;
  // The peer's global map last judged as a relay (RelayPolicy): its version and size, and when.
  // A newer one waits for its turn (max_relay_checks_per_update); until then the one judged stays.
  bool relay_judged = false;
  std::uint32_t relay_judged_version = 0;
  std::size_t relay_judged_size = 0;
  double last_relay_judged = -1e300;
  bool relayed = false;  // the global map is fused (it agreed with every map we hold), not the local one
  // What the global map takes from this peer.
  std::optional<MapSource> source;
  std::optional<MapSource> direct;              // ... and the one-hop map (never a relayed global map)
  std::optional<Pose2> candidate;               // an accepted alignment awaiting confirmation
  std::vector<Pose2> refuted;                   // alignments that lost to a relay's placement
  RobotId refuted_by = 0;                       // ... the last time, to this robot's relay
  std::optional<PeerKey> superseded_by;         // frozen, re-placed by this relay (see MapExchange::Build)
  std::map<PeerKey, double> last_refute_check;  // by relay: when its placement of this peer was last weighed
  std::optional<AlignmentResult> rendezvous;    // the newest accepted rendezvous fit, not yet weighed
  // The candidate's inliers as (our landmark id, its landmark id), sorted: what it rests on.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> candidate_pairs;
  bool continuity_prior = false;  // rendezvous holds an earlier incarnation's transform (same frame)

  // It contributes with a verified alignment (its landmarks may come through a relay).
  bool Aligned() const { return stage == PeerStage::kAligned || stage == PeerStage::kSuperseded; }
  // The map aligned: the peer's local map, or its global map when it sent no local one.
  const LandmarkMap& Map() const { return has_local && !local.empty() ? local : global; }
  // The peer can no longer speak (its writer is gone, or it is an own checkpoint).
  bool Frozen() const { return stale || own_checkpoint; }
  // ... or it sent no map for silent_after_s before `now`.
  bool Silent(double now, double silent_after_s) const { return Frozen() || now - last_heard > silent_after_s; }
  // The view for status, stats and tests, its liveness as of `now`.
  PeerReport Report(double now, double silent_after_s) const;
};

using PeerStates = std::map<PeerKey, PeerState>;

}  // namespace mapmesh
