#pragma once
// A robot's local map rebuilt from its closed submaps as a receiver holds them (issue J1): what
// an agent knows of a robot it never hears, whose submaps reached it through relays. The
// submaps are joined in chain order by a SubmapJoiner of the receiver's options; the map is the
// joined estimate with marginal covariances and the shape precision, as SubmapSlam::Map gives
// it without the open submap (landmark ids are the robot's keys, signatures unknown). Reads only
// the submaps it is given; changes only itself.
//
// Pure: Eigen only, no clocks, threads or random numbers.

#include <cstddef>
#include <span>

#include "common/map/landmark_map.h"
#include "common/map/submap_codec.h"
#include "common/slam/submap_joiner.h"

namespace mapmesh {

class ChainMap {
 public:
  explicit ChainMap(const JoinerOptions& options = {}) : joiner_(options) {}

  // Joins the chain's submaps after those already joined: chain[i] is submap i (not null), and
  // the first joined() of them are the ones joined before. Returns how many it joined now. A
  // submap the joiner refuses (malformed) ends the chain there for good: broken() is then true.
  std::size_t Extend(std::span<const WireSubmap* const> chain);

  std::size_t joined() const { return joiner_.submaps(); }
  bool broken() const { return broken_; }
  // The joined map (empty before the first submap).
  const LandmarkMap& map() const { return map_; }

 private:
  SubmapJoiner joiner_;
  LandmarkMap map_;
  bool broken_ = false;
};

}  // namespace mapmesh
