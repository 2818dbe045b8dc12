#pragma once
// How an agent builds its global maps from its own local map and its peers' placed maps
// (agent.fusion), chosen once when the exchange starts: Covariance Intersection into the cloned
// global map (the thesis's method and the default), or least-squares joining: of the own and
// the aligned peers' submap chains where the agent holds them (agent.slam cekf_submaps; each
// chain's open submap taken joined after its closed ones), else of
// the one-hop maps. Joining also places the chains of robots whose submaps reached the agent
// only through relays: each such chain's map is rebuilt from its submaps (ChainMap) and aligned
// against the own and one-hop maps, and used once a later alignment agrees (two hops and more);
// or, where an aligned peer's join placed the chain (its local map carries the placements), at
// that placement composed with the peer's, once the maps verify it.
// A chain whose time a later incarnation of its robot maps again (a lockstep restart replays the
// robot's stream) is left out, so that no measurement is joined twice.
// A back-end reads what it is given and changes only its own memory (association, relayed
// chains' maps and placements).

#include <map>
#include <memory>
#include <set>
#include <vector>

#include "agent/peer_state.h"
#include "common/map/submap_book.h"
#include "common/merge/global_map.h"
#include "common/merge/submap_placement.h"
#include "common/options/exchange_options.h"
#include "common/types/messages.h"

namespace mapmesh {

// What a back-end may use besides maps (issue J1): the closed submaps the agent holds, by
// identity (its own and its peers'), its own open submap (index: its closed ones' count; null
// for none) and the other robots' it took. Everything is the agent's and only pointed to: it must outlive the use.
struct SubmapInputs {
  const SubmapBook* book = nullptr;
  const WireSubmap* own_open = nullptr;
  // Each other robot incarnation's latest open submap taken, from its publisher or relayed once
  // it fell silent (SubmapRelay::open); it continues a chain where its index is the count of
  // the chain's closed submaps held. Null for none.
  const std::map<PeerKey, WireSubmap>* peers_open = nullptr;
  double now = 0.0;  // scenario time of the build (the exchange sets it): when alignments are due
  // Each peer incarnation's chain placements, from its latest local map (null for none).
  const std::map<PeerKey, std::vector<ChainPlacement>>* peers_placements = nullptr;
  // The robot incarnations heard themselves (listed by a tick, a map taken from the robot, the
  // agent's own): only these supersede an earlier chain (SubmapBook::Superseded). Null: any.
  const std::set<std::pair<RobotId, std::uint32_t>>* heard = nullptr;
};

// What the joining back-end's last solve on submap chains did (all zero before one).
struct JoiningReport {
  int solves = 0;         // solves on submap chains so far
  int chains_held = 0;    // robot incarnations of which the agent held submaps at the last build (own included)
  int chains = 0;         // chains offered at the last (own, then each aligned peer's) ...
  int chains_joined = 0;  // ... and joined (tied to the others by enough landmarks)
  // Sources (aligned peers' maps, placed relayed chains) at the last build whose landmarks the
  // global map takes from the CI build: their chain not joined, or no submap of them held.
  int sources_by_ci = 0;
  int submaps = 0;             // submaps joined ...
  int submaps_summarised = 0;  // ... among them those that entered as their chain's summary (agent.join_network_window)
  int iterations = 0;          // Levenberg-Marquardt iterations, both passes
  bool converged = false;
  bool solved = false;
  int ties = 0;          // pairings of landmarks across chains offered by the association ...
  int ties_dropped = 0;  // ... and dropped: two chains joined keep their references apart (submap_network.h)
  // Solves so far that ran the first pass (the rest judged the pairings on the last solve's
  // frames: submap_network.h), and among them those run again with it because the pairings
  // judged on the frames left a submap's residual too large.
  int first_passes = 0;
  // Solves so far that placed chains new to the join alone against the others' frames first
  // (submap_network.h), and so judged the pairings on frames without a first pass.
  int placed_alone = 0;
  int rechecks = 0;
  // ... among them those whose first pass kept the pairings the frames had (the submaps' excess
  // their own: remembered, RecheckMemo), and solves not rechecked since a submap beyond the
  // check was within what an earlier such recheck found its own.
  int rechecks_unchanged = 0;
  int rechecks_spared = 0;
  // Solves so far whose chains' information was calibrated by their residuals
  // (agent.join_calibrate_sigmas), and at the last one the chains whose information was divided
  // by a variance factor above 1, and the largest factor.
  int calibrated_solves = 0;
  int chains_calibrated = 0;
  double worst_variance_factor = 1.0;
  // Chains held only through relays (no map of their robot aligned): held at the last build,
  // placed (an alignment confirmed by a later one) and among them offered to the join; and the
  // alignments of their rebuilt maps tried so far, and refused as disagreeing with the one
  // before.
  int relayed_chains = 0;
  int relayed_placed = 0;
  int relayed_alignments = 0;
  int relayed_disagreements = 0;
  // Relayed chains placed where an aligned peer's join put them (composed with where ours put
  // the peer), and the verifications of such placements the maps refused so far.
  int relayed_by_placement = 0;
  int placements_refused = 0;
  // Chains left out at the last build: a later incarnation of their robot maps their time again
  // (SubmapBook::Superseded).
  int superseded_chains = 0;
  // One-hop peers' maps rebuilt from their chains at the last build: the chain held (closed
  // submaps relayed after the peer fell silent, or its open submap) had landmarks the last map
  // taken from the peer did not.
  int chains_extended = 0;
};

class FusionBackend {
 public:
  virtual ~FusionBackend() = default;
  // The global map (own local map with every placed source, relays included) and the one the
  // agent publishes (with the one-hop maps only, `direct`: nothing relayed goes out again).
  struct Built {
    GlobalMap global;
    GlobalMap published;
    JoiningReport joining;
    // Joining: where the last join put each other chain's first frame (the local map carries
    // them to the peers), in (robot, incarnation) order.
    std::vector<ChainPlacement> placements;
    // CI given the submaps (agent.ci_placement piecewise): how this build placed the peers'.
    PiecewiseStats piecewise;
  };
  virtual Built Build(const LandmarkMap& own_local, const std::vector<MapSource>& sources,
                      const std::vector<MapSource>& direct, const SubmapInputs& submaps = {}) = 0;
};

// The back-end options.global.method names, for robot `self` in its incarnation; joining
// aligns relayed chains with options.align, options.chain_join and the relay tolerances, its
// random draws seeded from `seed` (the agent's: scenario, robot, incarnation) and the chain.
std::unique_ptr<FusionBackend> MakeFusionBackend(RobotId self, std::uint32_t incarnation,
                                                 const ExchangeOptions& options, std::uint64_t seed);

}  // namespace mapmesh
