#include "common/merge/chain_map.h"

#include <stdexcept>

#include "common/slam/local_slam.h"

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
  if (added == 0) return 0;
  const JoinedMap& j = joiner_.last();
  map_ = LandmarkMap{};
  map_.landmarks.reserve(j.keys.size());
  for (std::size_t i = 0; i < j.keys.size(); ++i) {
    Landmark l;
    l.id = j.keys[i];
    l.mean = j.means[i];
    l.cov = j.Cov(i);
    map_.landmarks.push_back(l);
  }
  map_.shape_sigma_m = ShapeSigma(map_, [&](std::size_t a, std::size_t b) { return j.CrossCov(a, b); });
  return added;
}

}  // namespace mapmesh
