#pragma once
// MapExchange: what an agent does with its peers' maps (pure; time is the scenario time the
// agent has processed up to). For every peer, and every incarnation of a peer (each process
// start has its own map frame), it keeps the latest local and global map received, aligns the
// peer's map to its own local map (map_alignment.h), verifies every newer map of an aligned
// peer at the known transform before using it (so a corrupted or wrong map is refused, and the
// transform is refined as both maps grow; also on our own map alone, while the peer's map stays
// as it was, e.g. out of radio range), drops the alignment when verification keeps failing,
// aligns afresh as the maps grow (a false alignment accepted on small maps is replaced), uses
// an alignment only once a second, later one agrees with it, and
// rebuilds the cloned global map (global_map.h) from its local map and every aligned peer's
// latest verified map. How relaying, conflicts, frozen peers, bounded work and resume work,
// and why: docs/EXCHANGE.md.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <random>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "agent/exchange_options.h"
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

// What the agent knows about one peer incarnation (for status, stats and tests).
struct PeerReport {
  PeerKey key;
  bool own_checkpoint = false;     // an earlier incarnation of this agent
  double origin_stamp = 0.0;       // when the peer's frame was fixed
  int local_landmarks = 0, global_landmarks = 0;
  bool aligned = false;            // currently contributes with a verified alignment
  bool ever_aligned = false;
  bool dropped = false;            // was aligned, stopped verifying
  bool stale = false;              // its writer is gone (liveliness)
  double stale_since = 0.0;
  bool frozen = false;             // can no longer speak (stale, or an own checkpoint): kept as it is
  bool silent = false;             // frozen, or no map for silent_after_s
  double last_heard = 0.0;         // scenario time of its last map (ours, when it arrived)
  double aligned_since = 0.0;      // scenario time of the first acceptance
  Pose2 to_own;                    // the peer's frame in ours
  Eigen::Matrix3d to_own_cov = Eigen::Matrix3d::Zero();
  bool relayed = false;            // its global map is fused (not its local map)
  int relay_conflicts = 0;         // times its global map disagreed with another peer's map (not relayed then)
  int refuted = 0;                 // times our alignment of it lost to a relay's placement (then dropped, or re-placed when frozen) ...
  int replaced = 0;                // ... of which it was frozen and moved to the relay's placement ...
  bool superseded = false;         // ... and that relay, used now, brings its landmarks (its own copy is left out)
  RobotId refuted_by = 0;          // ... the last time, to this peer's relay
  int refuted_answers = 0;         // alignments refused for agreeing with a refuted one
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  // of the peer map aligned last, in its frame
  int attempts = 0, verifications = 0;
  int unconfirmed = 0;             // accepted alignments not (yet) confirmed by a later one
  int failures = 0;                // consecutive failed verifications (reset by a success)
  int rejected = 0;                // failed verifications in all
  int drops = 0;                   // times the alignment was dropped
  int realignments = 0;            // fresh alignments of an aligned peer (realign_on_growth) ...
  int corrections = 0;             // ... that replaced a transform they disagreed with
  int refinements = 0;             // transforms refined on our newer own map alone (refine_period_s)
  AlignmentVerdict last_verdict = AlignmentVerdict::kTooFewLandmarks;
};

class MapExchange {
 public:
  MapExchange(RobotId self, std::uint32_t incarnation, const ExchangeOptions& options, std::uint64_t seed);

  enum class Receipt { kAccepted, kStaleVersion, kVersionJump, kTooManyIncarnations };
  // A decoded map from a peer, received at scenario time `now`. Versions must grow within an
  // incarnation and kind (else kStaleVersion), and by no more than a publisher could have
  // published since (else kVersionJump: see ExchangeOptions::MaxVersionsPerS). A new incarnation beyond
  // max_incarnations, when no kept one can be evicted, is kTooManyIncarnations. A refused map
  // changes nothing.
  Receipt OnPeerMap(RobotId robot, std::uint32_t incarnation, MapKind kind, std::uint32_t version, double origin_stamp,
                    LandmarkMap map, double now);
  // The peer's writer came back (true) or went away (false): every incarnation of the robot.
  void OnPeerLiveliness(RobotId robot, bool alive, double now);
  // An earlier incarnation of this agent, from its checkpoint: aligned like any peer.
  void AddOwnCheckpoint(std::uint32_t incarnation, double origin_stamp, LandmarkMap local, LandmarkMap global);

  // Runs the alignments and verifications that are due against the own local map, then
  // rebuilds the global map. Returns true if any alignment changed.
  bool Update(const LandmarkMap& own_local, double now);

  const GlobalMap& global() const { return global_; }
  // The one-hop global map: the own local map fused with aligned peers' local maps (and an
  // earlier own incarnation's maps). This is what the agent publishes as its GLOBAL map.
  const GlobalMap& published() const { return published_; }
  // Earlier incarnations of this agent not aligned yet: a new checkpoint must carry them on.
  struct OwnEarlier {
    std::uint32_t incarnation = 0;
    double origin_stamp = 0.0;
    LandmarkMap local, global;
  };
  std::vector<OwnEarlier> UnalignedOwnCheckpoints() const;
  std::vector<PeerReport> Peers() const;
  // The last maps received from each peer incarnation (null where none), for the record.
  struct Received {
    PeerKey key;
    const LandmarkMap* local = nullptr;
    const LandmarkMap* global = nullptr;
  };
  std::vector<Received> ReceivedMaps() const;
  // Robots with at least one aligned incarnation, and robots whose writer is gone.
  std::vector<RobotId> AlignedRobots() const;
  std::vector<RobotId> StaleRobots() const;

 private:
  struct Peer {
    PeerReport report;
    LandmarkMap local, global;
    bool has_local = false, has_global = false;
    std::uint32_t local_version = 0, global_version = 0;
    double local_heard = 0.0, global_heard = 0.0;  // when the last map of each kind arrived
    bool changed = false;            // a map arrived since the last attempt or verification
    double last_attempt = -1e300;
    double last_refine = -1e300;     // last alignment, verification or refinement against our map
    std::size_t own_size_at_attempt = 0, peer_size_at_attempt = 0;
    // What the global map takes from this peer.
    std::optional<MapSource> source;
    std::optional<MapSource> direct;  // ... and the one-hop map (never a relayed global map)
    std::optional<Pose2> candidate;   // an accepted alignment awaiting confirmation
    std::vector<Pose2> refuted;       // alignments that lost to a relay's placement
    std::optional<PeerKey> superseded_by;  // frozen, re-placed by this relay (see Update)
    std::map<PeerKey, double> last_refute_check;  // by relay: when its placement of this peer was last weighed
  };
  // Aligns the peer's map to the own local map; when the answer is confirmed (confirm_alignments)
  // stores the transform and source and returns true. Returns false at once, trying nothing,
  // when this Update's alignment budget is spent.
  bool Align(Peer& p, const LandmarkMap& own_local, double now, bool reconsider_relay);
  // Whether a new incarnation of robot can be kept (max_incarnations), evicting one if need be.
  bool MakeRoomFor(RobotId robot);
  // Takes one alignment from this Update's budget; false when none is left.
  bool Spend();
  // The peer can no longer speak (stale, or an own checkpoint).
  bool Frozen(const Peer& p) const;
  // ... or sent no map for silent_after_s.
  bool Silent(const Peer& p) const;
  // An unaligned peer's alignment is due: after align_period_s, when its map changed or ours
  // grew by retry_growth (a frozen peer's map cannot change: whenever ours did).
  bool AttemptDue(const Peer& p, const LandmarkMap& own_local, double now) const;
  // Whether two transforms of a peer's frame agree at a point of its map (relay tolerances).
  bool Agree(const Pose2& a, const Pose2& b, const Eigen::Vector2d& at) const;
  // How `map` at `placement` compares with `witness` (a map in our frame) where they overlap:
  // agreeing means verifying there with relay_min_agreement of the overlapping landmarks as
  // inliers (their count in *inliers), at a transform that Agrees with the placement.
  enum class Overlap { kNone, kAgrees, kDisagrees };
  Overlap Compare(const LandmarkMap& witness, const LandmarkMap& map, const Pose2& placement,
                  int* inliers = nullptr) const;
  // The peer no longer contributes (its alignment is dropped); aligned again from `now` on.
  void Drop(Peer& p, double now);
  // A map of `size` landmarks has grown by retry_growth since it had `at_attempt`.
  bool Grew(std::size_t size, std::size_t at_attempt) const;
  // An aligned peer's fresh alignment is due (realign_on_growth).
  bool RealignDue(const Peer& p, const LandmarkMap& own_local, double now) const;
  // Uses an accepted (and confirmed) alignment r of the peer: its transform, and the source at it.
  void Use(Peer& p, const AlignmentResult& r, const LandmarkMap& own_local, bool reconsider_relay);
  // Checks the peer's newest map at the known transform; on success refines it and the source.
  bool Verify(Peer& p, const LandmarkMap& own_local);
  // The peer's map is the one verified already, ours has moved on (loop closures, more landmarks):
  // refits the transform on our map as it is now, keeping the choice of source. A fit that fails
  // or disagrees changes nothing (the peer's next map is verified as usual).
  void Refine(Peer& p, const LandmarkMap& own_local);
  // Which map of the peer the global map fuses: its global map when it verifies, else its local
  // map. Without reconsider_relay the earlier choice stays and only the transform is updated.
  // Sets refuted_ when it refuted another peer's alignment (see Conflicts above).
  void ChooseSource(Peer& p, const LandmarkMap& own_local, bool reconsider_relay);
  // Whether the peer's global map, at `to_own`, agrees with every other peer's one-hop
  // contribution it overlaps (relay_must_agree); if not, the first peer it disagrees with.
  bool RelayAgrees(const Peer& p, const Pose2& to_own, Peer** conflict = nullptr);
  // p's relay (at to_own) places q elsewhere than q's alignment: refutes q's alignment and
  // returns true when the relay's placement is better supported. A live q is dropped (the relay
  // then brings its landmarks); a frozen q is re-placed at the relay's placement, and only when
  // another map we hold supports it, so that its landmarks stay (superseded by the relay while
  // it is used).
  bool RefuteByRelay(const Peer& p, const Pose2& to_own, Peer& q, const LandmarkMap& own_local);
  // What the maps we hold independently of q (our local map and the other aligned peers' one-hop
  // maps) say of a placement of q's map.
  struct Evidence {
    int against = 0;     // maps that overlap it and disagree
    int supporters = 0;  // maps that overlap it and agree ...
    int inliers = 0;     // ... with this many matched landmarks in all
  };
  Evidence Weigh(const Peer& q, const Pose2& placement, const LandmarkMap& own_local) const;
  static const LandmarkMap& PeerMap(const Peer& p);

  RobotId self_;
  std::uint32_t incarnation_;
  ExchangeOptions options_;
  std::mt19937_64 rng_;
  std::map<PeerKey, Peer> peers_;
  double now_ = 0.0;      // of the Update in progress
  bool refuted_ = false;  // ... which refuted an alignment
  int budget_ = 0;        // ... and the alignments it may still run
  PeerKey next_turn_;     // the peer whose turn is first in the next Update (round robin)
  GlobalMap global_;
  GlobalMap published_;
};

}  // namespace mapmesh
