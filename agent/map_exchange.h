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

#include <cstdint>
#include <memory>
#include <random>
#include <set>
#include <vector>

#include "agent/fusion_backend.h"
#include "agent/peer_book.h"
#include "agent/peer_schedule.h"
#include "agent/peer_state.h"
#include "agent/relay_policy.h"
#include "common/merge/global_map.h"
#include "common/merge/rendezvous.h"
#include "common/options/exchange_options.h"

namespace mapmesh {

class MapExchange {
 public:
  MapExchange(RobotId self, std::uint32_t incarnation, const ExchangeOptions& options, std::uint64_t seed);

  using Receipt = PeerBook::Receipt;
  // A decoded map from a peer, received at scenario time `now` (PeerBook::OnPeerMap).
  Receipt OnPeerMap(RobotId robot, std::uint32_t incarnation, MapKind kind, std::uint32_t version, double origin_stamp,
                    LandmarkMap map, double now) {
    return book_.OnPeerMap(robot, incarnation, kind, version, origin_stamp, std::move(map), now);
  }
  // The peer's writer came back (true) or went away (false): every incarnation of the robot.
  void OnPeerLiveliness(RobotId robot, bool alive, double now) {
    book_.OnPeerLiveliness(robot, alive, now);
    now_ = now;
  }
  // Lockstep: exactly these peer incarnations are alive (an exchange tick's list); every other
  // one is stale.
  void SetLive(const std::set<PeerKey>& live, double now) {
    book_.SetLive(live, now);
    now_ = now;
  }
  // A rendezvous fit of a peer frame (rendezvous_tracker.h), weighed in the next Update of an
  // unaligned peer: verified against the maps at the fit (VerifyAlignment), it aligns the peer
  // when they match there; where they do not, or overlap too little to tell, it is refused
  // (counted apart). Ignored unless align_by includes rendezvous; kept only for peers whose map
  // arrived.
  void OnRendezvous(const PeerKey& key, const RendezvousFit& fit);
  // An earlier incarnation of this agent, from its checkpoint: aligned like any peer.
  void AddOwnCheckpoint(std::uint32_t incarnation, double origin_stamp, LandmarkMap local, LandmarkMap global) {
    book_.AddOwnCheckpoint(incarnation, origin_stamp, std::move(local), std::move(global));
  }

  // Peers' frames an earlier incarnation had placed (its checkpoint): PeerBook::AddCarried.
  void AddCarried(std::vector<PeerAlignment> carried) { book_.AddCarried(std::move(carried)); }
  // What a new checkpoint carries on of the peers' frames (PeerBook::Alignments).
  std::vector<PeerAlignment> Alignments(double frame_stamp) const { return book_.Alignments(frame_stamp); }

  // The submaps the fusion back-end may use from now on (fusion_backend.h): the book must
  // outlive the exchange's use of it.
  void SetSubmapInputs(SubmapInputs inputs) { submap_inputs_ = std::move(inputs); }
  // Runs the alignments and verifications that are due against the own local map, then
  // rebuilds the global map. Returns true if any alignment changed.
  bool Update(const LandmarkMap& own_local, double now);
  // Places at the identity every earlier own incarnation not placed yet whose session began at
  // origin_stamp, as this one's did: the feeder replayed the robot's stream to this incarnation
  // from the start, so that frame is ours (nothing to search for, nothing to verify), each with
  // its global map (what it had fused of others). Returns how many it placed; the global map
  // takes them at once, so that a checkpoint written before the next Update carries them. The
  // peers' frames carried in that frame (AddCarried) wait to be weighed from then on.
  int PlaceOwnCheckpointsAt(double origin_stamp, const LandmarkMap& own_local, double now);

  // How many Updates ran: alignments and the global maps change only in one (and when earlier
  // own incarnations are placed).
  std::uint64_t updates() const { return updates_; }
  const GlobalMap& global() const { return global_; }
  // The joining back-end's last solve on submap chains (fusion_backend.h).
  const JoiningReport& joining() const { return joining_; }
  // How the last CI build placed the peers' submaps (zero unless given them: fusion_backend.h).
  const PiecewiseStats& piecewise() const { return piecewise_; }
  // Where the joining back-end's last build put the other chains it joined (the agent's local
  // map carries them; empty with CI).
  const std::vector<ChainPlacement>& placements() const { return placements_; }
  // The one-hop global map: the own local map fused with aligned peers' local maps (and an
  // earlier own incarnation's maps). This is what the agent publishes as its GLOBAL map.
  const GlobalMap& published() const { return published_; }
  // Earlier incarnations of this agent not aligned yet: a new checkpoint must carry them on.
  using OwnEarlier = PeerBook::OwnEarlier;
  std::vector<OwnEarlier> UnalignedOwnCheckpoints() const { return book_.UnalignedOwnCheckpoints(); }
  // Every peer incarnation's report, its liveness as of the last update or liveness change.
  std::vector<PeerReport> Peers() const { return book_.Reports(now_); }
  // The last maps received from each peer incarnation (null where none), for the record.
  using Received = PeerBook::Received;
  std::vector<Received> ReceivedMaps() const { return book_.ReceivedMaps(); }
  // Robots with at least one aligned incarnation, and robots whose writer is gone.
  std::vector<RobotId> AlignedRobots() const { return book_.AlignedRobots(); }
  std::vector<RobotId> StaleRobots() const { return book_.StaleRobots(); }

 private:
  // What one Update did so far: whether an alignment changed, and the peers whose map (local or
  // global) was chosen anew.
  struct Round {
    bool changed = false;
    std::set<PeerKey> chosen;
  };
  // Carries out one turn of the schedule; true when it settled the peer (its later turns in
  // this Update are skipped).
  bool Take(const Turn& turn, const LandmarkMap& own_local, double now, Round& round);
  // Rebuilds the global maps from the own local map and the peers' chosen maps.
  void Build(const LandmarkMap& own_local);
  // Aligns the peer's map to the own local map (a turn of the schedule, which budgets them);
  // when the answer is confirmed (confirm_alignments) stores the transform and source and
  // returns true.
  bool Align(PeerState& p, const LandmarkMap& own_local, double now, bool reconsider_relay);
  // Weighs the peer's newest rendezvous fit against the maps; when they confirm it, uses it and
  // returns true.
  bool AlignByRendezvous(PeerState& p, const LandmarkMap& own_local, double now);
  // Marks a peer aligned by the answer just used.
  void MarkAligned(PeerState& p, AlignmentSource by, double now);
  // The peer no longer contributes (its alignment is dropped); aligned again from `now` on.
  void Drop(PeerState& p, double now);
  // Uses an accepted (and confirmed) alignment r of the peer: its transform, and the source at it.
  void Use(PeerState& p, const AlignmentResult& r, const LandmarkMap& own_local, bool reconsider_relay, double now);
  // Checks the peer's newest map at the known transform; on success refines it and the source
  // (judging its newest global map as a relay when judge_relay).
  bool Verify(PeerState& p, const LandmarkMap& own_local, double now, bool judge_relay);
  // The peer's map is the one verified already, ours has moved on (loop closures, more landmarks):
  // refits the transform on our map as it is now, keeping the choice of source. A fit that fails
  // or disagrees changes nothing (the peer's next map is verified as usual).
  void Refine(PeerState& p, const LandmarkMap& own_local, double now);
  // Which map of the peer the global map fuses: its global map when it verifies (and agrees
  // with what we hold: RelayPolicy), else its local map. Without reconsider_relay the earlier
  // choice stays and only the transform is updated. Sets refuted_ when it refuted another
  // peer's alignment.
  void ChooseSource(PeerState& p, const LandmarkMap& own_local, bool reconsider_relay, double now);
  // p's relay (at to_own) places q elsewhere than q's alignment. When RelayPolicy::Refutation
  // says ours is the false one, a live q is dropped (the relay then brings its landmarks) and a
  // frozen q is re-placed at the relay's placement (superseded by the relay while it is used).
  // Weighed at most once per align period for each relay. Returns true when q was refuted.
  bool RefuteByRelay(const PeerState& p, const Pose2& to_own, PeerState& q, const LandmarkMap& own_local, double now);

  RobotId self_;
  std::uint32_t incarnation_;
  ExchangeOptions options_;
  RelayPolicy relay_{options_};
  std::mt19937_64 rng_;
  PeerBook book_{self_, options_};
  double now_ = 0.0;      // the last update's or liveness change's scenario time (the reports' liveness)
  bool refuted_ = false;  // the Update in progress refuted an alignment
  PeerKey next_turn_;     // the peer whose turn is first in the next Update (round robin)
  std::unique_ptr<FusionBackend> fusion_;  // agent.fusion, chosen once
  SubmapInputs submap_inputs_;
  JoiningReport joining_;
  PiecewiseStats piecewise_;
  std::vector<ChainPlacement> placements_;
  GlobalMap global_;
  GlobalMap published_;
  std::uint64_t updates_ = 0;
  double rendezvous_gate_;  // chi-square 3 dof at rendezvous_gate_probability: the maps' transform must lie
                            // this close to the rendezvous fit (TransformDistance2)
};

}  // namespace mapmesh
