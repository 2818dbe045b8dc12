#pragma once
// How an agent builds its global maps from its own local map and its peers' placed maps
// (agent.fusion), chosen once when the exchange starts: Covariance Intersection into the cloned
// global map (the thesis's method and the default), or least-squares joining of the one-hop
// maps. A back-end reads the maps it is given and changes only its own association memory.

#include <memory>
#include <vector>

#include "common/merge/global_map.h"

namespace mapmesh {

class FusionBackend {
 public:
  virtual ~FusionBackend() = default;
  // The global map (own local map with every placed source, relays included) and the one the
  // agent publishes (with the one-hop maps only, `direct`: nothing relayed goes out again).
  struct Built {
    GlobalMap global;
    GlobalMap published;
  };
  virtual Built Build(const LandmarkMap& own_local, const std::vector<MapSource>& sources,
                      const std::vector<MapSource>& direct) = 0;
};

// The back-end options.method names, for robot `self` in its incarnation.
std::unique_ptr<FusionBackend> MakeFusionBackend(RobotId self, std::uint32_t incarnation,
                                                 const GlobalMapOptions& options);

}  // namespace mapmesh
