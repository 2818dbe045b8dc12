#pragma once
// Covariance Intersection on submaps, piecewise (issue J1: agent.fusion ci with agent.slam
// cekf_submaps). A peer's local map is a chain of submaps, each rigid to within its own small
// errors, but the chain bends with the peer's heading drift, so one rigid transform cannot lay
// the whole map over ours. Each submap is placed on its own instead:
// - it starts where the peer's whole map puts it: the submap's frame in that map (the rigid fit
//   of its landmarks onto the map's of the same keys) relative to the last fitted submap's, or
//   at the whole map's alignment before any was fitted; where the whole map holds fewer than
//   three of its landmarks, at the previous submap's placement composed with that submap's end
//   pose (the origin of the next frame; the first submap's frame is the map's). The covariance
//   grows along the chain by the end poses'. (The whole map is the robot's joint estimate of
//   its submaps: on park4, placing by the end poses alone put the peers' landmarks the holder
//   never saw up to twice as far off);
// - its landmarks are paired with the target map's (the holder's local map, in the own frame):
//   each with the target's nearest within pair_radius_m, when the second nearest is
//   unique_ratio times farther; pairing and fit alternate `iterations` times, from that start
//   and from the whole map's alignment;
// - with min_pairs pairs or more, the weighted least-squares fit of the submap's frame on them
//   (weights: the inverse of both landmarks' covariances) places it, unless its residual fails the chi-square gate (gate_probability) or its RMS exceeds
//   max_rms_m; of the two starts, the accepted fit with more pairs. Without one the submap
//   stays at its start. The fit's covariance takes the target's landmarks as errors of
//   unknown correlation (they are one map's, and that map bends): the sum of n such terms has at
//   most n times the sum of their covariances. Taken as independent, the placements were
//   overconfident (the circle pair's global NEES 3.1 median, 11.7 worst).
// Each placed submap is a source of its own for the cloned global map (global_map.h): its
// landmarks in its frame with their marginal covariances (ids: the robot's keys), the placement
// and its covariance. The whole map's landmarks that no submap given holds follow as one more
// source at the whole map's alignment.
//
// Pure: Eigen only; reads only its arguments.

#include <span>
#include <vector>

#include "common/map/landmark_map.h"
#include "common/map/submap_codec.h"
#include "common/merge/global_map.h"

namespace mapmesh {

struct PiecewiseOptions {
  double pair_radius_m = 0.75;      // a submap landmark pairs with the target's nearest within this ...
  double unique_ratio = 2.0;        // ... when the second nearest is this many times farther
  int min_pairs = 3;                // pairs a fit needs
  int iterations = 3;               // pairings and fits, alternated
  double gate_probability = 0.999;  // the fit's residual (chi-square, 2 pairs - 3 dof) must pass this ...
  double max_rms_m = 0.3;           // ... and its RMS stay within this
};

struct PiecewiseStats {
  int submaps = 0;  // submaps placed ...
  int fitted = 0;   // ... by their own fit on the target
  int refused = 0;  // ... whose fit the gates refused (placed at their start)
  int chained = 0;  // ... at their start (too few pairs, or refused)
  int pairs = 0;    // pairs in the accepted fits
  int rest = 0;     // the whole map's landmarks no submap holds

  PiecewiseStats& operator+=(const PiecewiseStats& o) {
    submaps += o.submaps;
    fitted += o.fitted;
    refused += o.refused;
    chained += o.chained;
    pairs += o.pairs;
    rest += o.rest;
    return *this;
  }
};

// The piecewise sources of one peer: `whole` is its local map placed by its alignment (its
// robot, incarnation, map, to_own and covariance); chain[i] is its submap i (not null; closed
// ones, then possibly the open one continuing them). An empty chain returns {whole}.
std::vector<MapSource> PlaceSubmapsPiecewise(const LandmarkMap& target, const MapSource& whole,
                                             std::span<const WireSubmap* const> chain,
                                             const PiecewiseOptions& options = {}, PiecewiseStats* stats = nullptr);

}  // namespace mapmesh
