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

}  // namespace mapmesh
