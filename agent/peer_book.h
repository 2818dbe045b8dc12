#pragma once
// PeerBook: what an agent holds of its peers, one PeerState per peer incarnation: their maps
// as received (versions checked, incarnations bounded), their liveness, the earlier
// incarnations of the agent itself; and the views of them that others read (reports for status,
// facts for the schedule, the maps for the record). It decides nothing about alignment or
// fusion: MapExchange does, on the states it holds. Pure; time is the agent's scenario time.

#include <cstdint>
#include <optional>
#include <set>
#include <vector>

#include "agent/peer_schedule.h"
#include "agent/peer_state.h"
#include "common/io/checkpoint.h"
#include "common/options/exchange_options.h"

namespace mapmesh {

class PeerBook {
 public:
  PeerBook(RobotId self, const ExchangeOptions& options) : self_(self), options_(options) {}

  enum class Receipt { kAccepted, kStaleVersion, kVersionJump, kTooManyIncarnations };
  // A decoded map from a peer, received at scenario time `now`. Versions must grow within an
  // incarnation and kind (else kStaleVersion), and by no more than a publisher could have
  // published since (else kVersionJump: see ExchangeOptions::MaxVersionsPerS). A new incarnation
  // beyond max_incarnations, when no kept one can be evicted, is kTooManyIncarnations. A refused
  // map changes nothing.
  Receipt OnPeerMap(RobotId robot, std::uint32_t incarnation, MapKind kind, std::uint32_t version, double origin_stamp,
                    LandmarkMap map, double now);
  // The peer's writer came back (true) or went away (false): every incarnation of the robot.
  void OnPeerLiveliness(RobotId robot, bool alive, double now);
  // Lockstep: exactly these peer incarnations are alive (an exchange tick's list).
  void SetLive(const std::set<PeerKey>& live, double now);
  // An earlier incarnation of this agent, from its checkpoint: frozen, aligned like any peer.
  void AddOwnCheckpoint(std::uint32_t incarnation, double origin_stamp, LandmarkMap local, LandmarkMap global);

  // Peers' frames an earlier incarnation of this agent had placed (its checkpoint, issue R3), each
  // in the agent's frame that began at its frame_stamp. Kept until UseCarriedIn names that frame
  // as this session's; from then on a peer incarnation of the robot whose frame began where the
  // carried one's did, and that is not aligned, waits to be weighed on the maps at the carried
  // transform (like a later incarnation of an aligned peer: OnPeerMap), instead of a search.
  void AddCarried(std::vector<PeerAlignment> carried);
  // This session's frame began at frame_stamp (an own checkpoint was placed by continuity): the
  // carried alignments in that frame apply. Returns how many peers now wait to weigh one.
  int UseCarriedIn(double frame_stamp);
  // What a new checkpoint carries on: every aligned peer's frame in this session's (frame_stamp),
  // and each carried alignment whose peer incarnation is not aligned now.
  std::vector<PeerAlignment> Alignments(double frame_stamp) const;

  PeerStates& states() { return peers_; }
  const PeerStates& states() const { return peers_; }

  // The schedule's view of every peer at `now`, in key order.
  std::vector<PeerFacts> Facts(double now) const;
  // Every peer's report, its liveness as of `now`.
  std::vector<PeerReport> Reports(double now) const;
  // The last maps received from each peer incarnation (null where none), for the record.
  struct Received {
    PeerKey key;
    const LandmarkMap* local = nullptr;
    const LandmarkMap* global = nullptr;
  };
  std::vector<Received> ReceivedMaps() const;
  // Earlier incarnations of this agent not aligned yet: a new checkpoint must carry them on.
  struct OwnEarlier {
    std::uint32_t incarnation = 0;
    double origin_stamp = 0.0;
    LandmarkMap local, global;
  };
  std::vector<OwnEarlier> UnalignedOwnCheckpoints() const;
  // Robots with at least one aligned incarnation, and robots whose writer is gone.
  std::vector<RobotId> AlignedRobots() const;
  std::vector<RobotId> StaleRobots() const;

 private:
  // Whether a new incarnation of robot can be kept (max_incarnations), evicting one if need be.
  bool MakeRoomFor(RobotId robot, double now);
  void SetStale(PeerState& p, bool stale, double now);
  // A later incarnation of p's robot began at p's origin stamp (the feeder replayed the same
  // stream to it, so its map grows into a superset of p's) and holds at least as many landmarks.
  bool CarriedByLater(const PeerState& p) const;
  // p waits to weigh a transform of its frame already known: an aligned earlier incarnation's
  // of the same robot and frame, or a carried one in this session's frame.
  void SeedContinuityPrior(PeerState& p) const;

  RobotId self_;
  ExchangeOptions options_;
  PeerStates peers_;
  std::vector<PeerAlignment> carried_;
  std::optional<double> carried_frame_;  // this session's frame, once an own checkpoint is placed in it
};

}  // namespace mapmesh
