#include "common/merge/chain_map.h"

#include <stdexcept>

#include "common/slam/submap_slam.h"

namespace mapmesh {

std::size_t ChainMap::Extend(std::span<const WireSubmap* const> chain) {
  std::size_t added = 0;
  while (!broken_ && joiner_.submaps() < chain.size()) {
    const WireSubmap& s = *chain[joiner_.submaps()];
    try {
      joiner_.Add({s.x, s.Covariance(), s.keys});
    } catch (const std::invalid_argument&) {
      broken_ = true;
      break;
    }
    ++added;
  }
  if (added > 0) map_ = JoinedLandmarkMap(joiner_.last(), false);
  return added;
}

const LandmarkMap& ChainMap::MapWith(const WireSubmap* open) {
  if (open == nullptr || broken_ || open->id.index != joiner_.submaps()) return map_;
  if (with_open_ && with_open_->joined == joiner_.submaps() && with_open_->index == open->id.index &&
      with_open_->closed_s == open->closed_s) {
    return with_open_->map;
  }
  const SubmapEstimate estimate{open->x, open->Covariance(), open->keys};
  try {
    with_open_ = WithOpen{joiner_.submaps(), open->id.index, open->closed_s,
                          JoinedLandmarkMap(joiner_.Solve(&estimate), false)};
  } catch (const std::invalid_argument&) {
    return map_;
  }
  return with_open_->map;
}

}  // namespace mapmesh
