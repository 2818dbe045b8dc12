#pragma once
// How an agent judges a peer's global map, a relay of what that peer learned from others: where
// it overlaps a map the agent holds, the two must agree (else it is not fused), and when a
// relay places another peer elsewhere than the agent's own alignment of it, the evidence of
// every other map decides which is false (docs/EXCHANGE.md "Relay" and "Conflicts"). Pure: it
// reads the peers' state and changes none of it; MapExchange acts on its answers.

#include <optional>
#include <random>

#include "agent/peer_state.h"
#include "common/options/exchange_options.h"

namespace mapmesh {

class RelayPolicy {
 public:
  explicit RelayPolicy(const ExchangeOptions& options) : options_(options) {}

  // Whether two transforms of a peer's frame agree at a point of its map (relay tolerances).
  bool Agree(const Pose2& a, const Pose2& b, const Eigen::Vector2d& at) const;
  // How `map` at `placement` compares with `witness` (a map in our frame) where they overlap:
  // agreeing means verifying there with relay_min_agreement of the overlapping landmarks as
  // inliers (their count in *inliers), at a transform that Agrees with the placement.
  enum class Overlap { kNone, kAgrees, kDisagrees };
  Overlap Compare(const LandmarkMap& witness, const LandmarkMap& map, const Pose2& placement,
                  int* inliers = nullptr) const;
  // The first peer whose one-hop contribution p's global map, at to_own, disagrees with where
  // they overlap (relay_must_agree); nullopt when it agrees with every one.
  std::optional<PeerKey> FirstConflict(const PeerStates& peers, const PeerState& p, const Pose2& to_own) const;
  // What the maps we hold independently of q (our local map and the other aligned peers'
  // one-hop maps) say of a placement of q's map.
  struct Evidence {
    int against = 0;     // maps that overlap it and disagree
    int supporters = 0;  // maps that overlap it and agree ...
    int inliers = 0;     // ... with this many matched landmarks in all
  };
  Evidence Weigh(const PeerStates& peers, const PeerState& q, const Pose2& placement,
                 const LandmarkMap& own_local) const;
  // p's relay (at to_own) and our alignment of q place q differently. Returns the relay's
  // placement of q (its covariance including p's) when the evidence refutes our alignment: the
  // relay's placement is better supported, or ours is opposed more than supported. A frozen q
  // is refuted only when another map we hold supports the relay's placement (its landmarks are
  // then moved there rather than lost).
  std::optional<AlignmentResult> Refutation(const PeerStates& peers, const PeerState& p, const Pose2& to_own,
                                            const PeerState& q, const LandmarkMap& own_local,
                                            std::mt19937_64& rng) const;

 private:
  ExchangeOptions options_;
};

}  // namespace mapmesh
