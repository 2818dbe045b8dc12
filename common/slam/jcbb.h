#pragma once
// Joint compatibility branch and bound (Neira & Tardós 2001): the one search behind the local
// SLAM's data association and the global map's landmark matching.
//
// Items (observations; a peer's landmarks) each have candidate targets (landmarks; clusters),
// tried in the given order (closest first is fastest). A hypothesis pairs some items with
// distinct targets. It is jointly compatible when the joint squared Mahalanobis distance of its
// pairings is below the chi-squared quantile at gate_probability with 2 degrees of freedom per
// pairing; the caller computes that distance, since what correlates the pairings differs (the
// robot pose and map in the filter, the alignment in the global map). The search returns the
// jointly compatible hypothesis with the most pairings, and among those the lowest joint
// distance, found within max_nodes nodes.

#include <functional>
#include <span>
#include <vector>

namespace mapmesh {

struct JcbbPairing {
  int item = 0;
  int option = 0;  // index into the item's candidate list
  int target = 0;  // candidates[item][option]
};

// The joint squared distance of the pairings (in item order); infinity when it is undefined.
using JointDistance = std::function<double(std::span<const JcbbPairing>)>;

struct JcbbResult {
  std::vector<int> option;  // per item: the index of its chosen candidate, or -1 unpaired
  int pairings = 0;
  double joint_d2 = 0.0;
  long nodes = 0;           // search nodes visited
  bool node_limit = false;  // the search stopped at max_nodes: the best found so far
};

JcbbResult JointCompatibility(const std::vector<std::vector<int>>& candidates, const JointDistance& joint_d2,
                              double gate_probability, long max_nodes);

}  // namespace mapmesh
