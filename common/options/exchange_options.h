#pragma once
// The settings of an agent's map exchange (agent/map_exchange.h; docs/EXCHANGE.md explains the
// rules they tune). Header-only: the scenario composes them (common/config/scenario.h).

#include <cstdint>

#include "common/merge/global_map.h"
#include "common/merge/map_alignment.h"
#include "common/options/submap_relay_options.h"
#include "common/slam/submap_joiner.h"
#include "common/types/choice.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

// The alignment an agent runs on its peers' maps: AlignmentOptions, except that where a
// transform lays the peer's map over ground we have mapped, half of its landmarks there (not
// 0.3) must find partners. In the park's rows of trees 1.5 m apart, false alignments passed
// at 0.3 (6 of 16 matched); true ones match 0.8-1.0 there and in MRCLAM and Victoria Park.
inline AlignmentOptions ExchangeAlignment() {
  AlignmentOptions o;
  o.min_overlap_ratio = 0.5;
  return o;
}

// Parts of the exchange that the unit tests switch off one at a time, to show what each one
// prevents. They are not settings: a run always has them all on.
struct ExchangeAblations {
  bool confirm_alignments = true;  // an alignment is used once a later, independent one agrees with it
  bool realign_on_growth = true;   // a live aligned peer is aligned afresh when either map grew by retry_growth
                                   // (at most every align_period_s); an accepted answer replaces the transform
  bool relay_must_agree = true;    // a relay must agree with the other aligned peers' maps it overlaps
  bool refute_by_relay = true;     // a better supported relay refutes our direct alignment
};

// Where alignments come from (agent.align_by): map overlap (triangles and RANSAC), rendezvous
// (robots that saw each other, rendezvous_tracker.h), or both. Either is verified against the maps.
enum class AlignBy { kBoth, kOverlap, kRendezvous };
inline constexpr ChoiceTable<AlignBy, 3> kAlignBy{
    {{AlignBy::kBoth, "both"}, {AlignBy::kOverlap, "overlap"}, {AlignBy::kRendezvous, "rendezvous"}}};

// How a CI-fusing agent places a peer's map whose closed submaps it holds (agent.slam
// cekf_submaps): each submap on its own against the own map (submap_placement.h), or the whole
// map at its alignment. Without submaps the whole map either way.
enum class CiPlacement { kPiecewise, kRigid };
inline constexpr ChoiceTable<CiPlacement, 2> kCiPlacement{
    {{CiPlacement::kPiecewise, "piecewise"}, {CiPlacement::kRigid, "rigid"}}};

struct ExchangeOptions {
  AlignBy align_by = AlignBy::kBoth;               // agent.align_by
  CiPlacement ci_placement = CiPlacement::kRigid;  // agent.ci_placement
  bool ByOverlap() const { return align_by != AlignBy::kRendezvous; }
  bool ByRendezvous() const { return align_by != AlignBy::kOverlap; }
  double align_period_s = 5.0;     // agent.align_period_s: an unaligned peer is tried again this often, when its
                                   // map changed ...
  double retry_growth = 0.2;       // ... or ours grew by this share
  int drop_after_failures = 2;     // agent.drop_after_failures: consecutive failed verifications drop the alignment
  double refine_period_s = 5.0;    // agent.refine_period_s: a live aligned peer that sent nothing new has its transform
                                   // refined on our own map as it is now, this often (0: only when the peer's
                                   // map changes)
  bool relay_global_maps = true;   // agent.relay_global_maps: fuse a peer's global map when it agrees with the
                                   // peer's alignment
  double relay_tolerance_m = 1.0;  // ... within this (at the map's centroid) ...
  double relay_tolerance_deg = 2.0;  // ... and this (two transforms within both agree, for confirmations too)
  // ... and where it overlaps another aligned peer's map, verifies against that map too (a
  // relay must not place a robot elsewhere than we do; ExchangeAblations::relay_must_agree) ...
  double relay_min_agreement = 0.6;  // ... with this share of the overlapping landmarks as inliers (in
                                     // the unit test a relay partly 3 m off scores 0.49, a true one 0.97)
  // A relay that places a peer elsewhere than our alignment does, and is better supported by the
  // maps we hold, refutes our alignment (at most every align_period_s) ...
  double refute_min_offset_m = 10.0;    // ... when the two place the peer's map centroid this far apart ...
  double refute_min_offset_deg = 10.0;  // ... or turned by this much (closer, they are two fits of one alignment,
                                        // as of Victoria Park's bent maps, 3-5 m and 2-3 degrees apart) ...
  double refute_min_share = 0.5;        // ... and the relay's placement matches this share of the peer's map
                                        // (the relay holds that map, not a stretch of it by coincidence)
  double map_publish_period_s = 2.0;    // agent.map_publish_period_s: scenario seconds between an agent's map
                                        // publications
  double silent_after_s = 0.0;          // a peer that sent no map for this long (scenario s) is silent; 0: 3
                                        // map periods
  int max_alignments_per_update = 4;    // agent.max_alignments_per_update: full alignments (first, retried and fresh
                                        // ones) per Update, round robin ...
  int peers_per_alignment = 16;         // agent.peers_per_alignment: ... or one per this many peers known, if more
                                        // (0: never more), so that every peer's turn comes as often at any size
  int max_rendezvous_per_update = 64;   // agent.max_rendezvous_per_update: rendezvous fits weighed against the maps
                                        // per Update, round robin with the alignments
  int max_relay_checks_per_update = 4;  // agent.max_relay_checks_per_update: relays (peers' newer global maps) judged
                                        // per Update, those that grew most first; the others keep the global map
                                        // judged last (docs/EXCHANGE.md "Bounded work") ...
  int max_relay_comparisons_per_update = 64;  // agent.max_relay_comparisons_per_update: ... and fewer when judging
                                              // them would compare more maps than this: a relay is compared with
                                              // every aligned peer's map (one relay per Update at least)
  // A map's version may exceed the last one received by this plus MaxVersionsPerS() times the
  // scenario seconds since (and any version that rate times now).
  std::uint32_t version_slack = 64;
  int max_incarnations = 8;  // incarnations kept per robot; a newer one evicts one never aligned and frozen
  AlignmentOptions align = ExchangeAlignment();  // align.search: agent.align_search
  // A rendezvous fit is verified by the maps at it with this many inliers (not align.min_inliers):
  // a blind search over the whole map must beat every chance match there, a check at a transform
  // found independently only the few near it. In the park, robots that meet have mapped 3-5
  // common trees, and every one of them matches; laid 5 m off, none does.
  int rendezvous_min_inliers = 3;
  double rendezvous_gate_probability = 0.999;  // the maps' transform must lie within this gate of the fit
  GlobalMapOptions global;
  SubmapRelayOptions submaps;  // closed submaps held and relayed (issue J1); zero periods resolved by Submaps()
  // The joining back-end rebuilds the map of a robot it holds submaps of but aligned no map of
  // (its submaps were relayed) with the agent's own joiner options (agent.join_window,
  // agent.join_relinearise_m): AgentOptions::Read copies them here.
  JoinerOptions chain_join{.relinearise_m = 0.1};
  // agent.join_network_window: the joining back-end joins each chain's last this many closed
  // submaps (and its open one) one by one, and the older ones as one summary of them (the
  // chain's own join: ChainMap::Summary), so that the join's size stops growing with the run's
  // length. Not the default (none summarised): on park4 the summaries make the join dense and
  // dearer (docs/EXPERIMENTS.md "J2: old submaps summarised").
  int network_window = limits::kMaxJoinNetworkWindow;
  // agent.join_calibrate_sigmas: NetworkOptions::calibrate_sigmas (0: the chains' information as
  // their submaps give it). On the simulated park nothing is calibrated in the end (13 solves of
  // 4040 ran it, every final factor 1, the maps the same); on MRCLAM 1 and 7 the median gap falls
  // from 1.13 and 1.36 to 1.06 and 1.30 (docs/EXPERIMENTS.md).
  double join_calibrate_sigmas = 3.0;
  ExchangeAblations test_only;  // all on outside unit tests

  // silent_after_s resolved.
  double SilentAfterS() const { return silent_after_s > 0 ? silent_after_s : 3.0 * map_publish_period_s; }
  // How fast a peer's map versions can grow: one of each kind per period, twice over.
  double MaxVersionsPerS() const { return 2.0 / map_publish_period_s; }
  // submaps with its zero periods resolved: 3 map periods each; an open submap is a silent
  // robot's after SilentAfterS.
  SubmapRelayOptions Submaps() const {
    SubmapRelayOptions o = submaps;
    if (o.resend_after_s <= 0) o.resend_after_s = 3.0 * map_publish_period_s;
    if (o.advert_max_age_s <= 0) o.advert_max_age_s = 3.0 * map_publish_period_s;
    if (o.open_silent_after_s <= 0) o.open_silent_after_s = SilentAfterS();
    return o;
  }

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md).
  template <typename Reader>
  void Read(Reader& r) {
    global.Read(r);
    r.GetChoice("align_by", align_by, kAlignBy);
    r.GetChoice("ci_placement", ci_placement, kCiPlacement);
    r.GetInRange("join_network_window", network_window, 0, limits::kMaxJoinNetworkWindow);
    r.GetZeroOrInRange("join_calibrate_sigmas", join_calibrate_sigmas, 0.5, 100.0);
    r.GetChoice("align_search", align.search, kTransformSearch);
    r.GetInRange("align_period_s", align_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetZeroOrInRange("refine_period_s", refine_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetInRange("drop_after_failures", drop_after_failures, 1, limits::kMaxDropAfterFailures);
    r.Get("relay_global_maps", relay_global_maps);
    r.GetInRange("map_publish_period_s", map_publish_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetZeroOrInRange("silent_after_s", silent_after_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetInRange("max_alignments_per_update", max_alignments_per_update, 1, limits::kMaxAlignmentsPerUpdate);
    r.GetInRange("peers_per_alignment", peers_per_alignment, 0, limits::kMaxAlignmentsPerUpdate);
    r.GetInRange("max_rendezvous_per_update", max_rendezvous_per_update, 1, limits::kMaxAlignmentsPerUpdate);
    r.GetInRange("max_relay_checks_per_update", max_relay_checks_per_update, 1, limits::kMaxAlignmentsPerUpdate);
    r.GetInRange("max_relay_comparisons_per_update", max_relay_comparisons_per_update, 1,
                 limits::kMaxRelayComparisonsPerUpdate);
    int send_bytes = static_cast<int>(submaps.send_bytes);
    r.GetInRange("submap_send_bytes", send_bytes, 1, limits::kMaxSubmapSendBytes);
    submaps.send_bytes = static_cast<std::size_t>(send_bytes);
    r.GetZeroOrInRange("submap_resend_after_s", submaps.resend_after_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    int held = static_cast<int>(submaps.max_held);
    r.GetInRange("max_submaps_held", held, 1, limits::kMaxSubmapsHeld);
    submaps.max_held = static_cast<std::size_t>(held);
    // Byte bounds (issue R3): a submap, a chain and all of them.
    int submap_bytes = static_cast<int>(submaps.max_submap_bytes);
    r.GetInRange("max_submap_bytes", submap_bytes, limits::kMinSubmapBytes, limits::kMaxSubmapBytes);
    submaps.max_submap_bytes = static_cast<std::size_t>(submap_bytes);
    int chain_bytes = static_cast<int>(submaps.max_chain_bytes);
    r.GetInRange("max_chain_bytes", chain_bytes, limits::kMinSubmapBytes, limits::kMaxSubmapBytesHeld);
    submaps.max_chain_bytes = static_cast<std::size_t>(chain_bytes);
    int held_bytes = static_cast<int>(submaps.max_bytes_held);
    r.GetInRange("max_submap_bytes_held", held_bytes, limits::kMinSubmapBytes, limits::kMaxSubmapBytesHeld);
    submaps.max_bytes_held = static_cast<std::size_t>(held_bytes);
  }
};

}  // namespace mapmesh
