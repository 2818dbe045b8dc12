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
#include <optional>
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
  // The joined map with the chain's open submap `open` after the submaps joined (as
  // SubmapSlam::Map gives it with its open submap; with none joined, the open one's map alone);
  // map() when open is null, does not continue the chain (its index is not joined()), the chain
  // is broken or the joiner refuses it. The last one is kept: the same open submap (identity and closed_s: one version
  // of it) on the same chain is not solved again.
  const LandmarkMap& MapWith(const WireSubmap* open);

  // The submaps joined as one submap (issue J2: a network join's old submaps summarised): in
  // the chain's first frame, the end pose of the last one joined (the next one's frame) and
  // every landmark's mean as joined, with their joint covariance, named by `last` (the last
  // submap joined) with kSummaryIndexBit set in its index. The join of a network that takes
  // it in place of those submaps is theirs to the linearisation within the chain (each chain's
  // submaps are independent of every other's). Null before a submap is joined, when the chain
  // is broken, or when the covariance cannot be written. Kept until another submap is joined.
  const WireSubmap* Summary(const WireSubmap& last);

 private:
  SubmapJoiner joiner_;
  LandmarkMap map_;
  bool broken_ = false;
  struct WithOpen {
    std::size_t joined = 0;
    std::uint32_t index = 0;
    double closed_s = 0.0;
    LandmarkMap map;
  };
  std::optional<WithOpen> with_open_;
  std::optional<WireSubmap> summary_;  // of the first summary_joined_ submaps
  std::size_t summary_joined_ = 0;
};

// A summary's id: the last submap's it stands for, with this bit in the index (no chain holds
// 2^31 submaps), so that it is never taken for that submap.
inline constexpr std::uint32_t kSummaryIndexBit = 0x80000000u;

}  // namespace mapmesh
