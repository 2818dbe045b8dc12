#include "agent/fusion_backend.h"

#include "common/merge/map_joining.h"

namespace mapmesh {
namespace {

// The cloned global map (thesis 2.3.2): each source's landmarks associated with the map's and
// fused by Covariance Intersection (or the estimator options.method names).
class CloneFusion : public FusionBackend {
 public:
  CloneFusion(RobotId self, std::uint32_t incarnation, const GlobalMapOptions& options)
      : self_(self), incarnation_(incarnation), options_(options) {}
  Built Build(const LandmarkMap& own_local, const std::vector<MapSource>& sources,
              const std::vector<MapSource>& direct) override {
    Built b;
    b.global = BuildGlobalMap(own_local, self_, sources, options_, incarnation_, &global_memo_);
    b.published = BuildGlobalMap(own_local, self_, direct, options_, incarnation_, &published_memo_);
    return b;
  }

 private:
  RobotId self_;
  std::uint32_t incarnation_;
  GlobalMapOptions options_;
  AssociationMemo global_memo_, published_memo_;  // each map's ambiguous groups, from its last build
};

// Least-squares joining of the one-hop local maps only (map_joining.h: each robot's
// measurements enter once); the gates of a CI build give the association. Relays are not used:
// a relayed global map mixes information of unknown origin.
class JoiningFusion : public FusionBackend {
 public:
  JoiningFusion(RobotId self, std::uint32_t incarnation, const GlobalMapOptions& options)
      : self_(self), incarnation_(incarnation), association_(options) {
    association_.method = FusionMethod::kCiConstant;
  }
  Built Build(const LandmarkMap& own_local, const std::vector<MapSource>&,
              const std::vector<MapSource>& direct) override {
    const GlobalMap associated = BuildGlobalMap(own_local, self_, direct, association_, incarnation_, &memo_);
    Built b;
    b.global = JoinMaps(own_local, self_, incarnation_, direct, associated);
    b.published = b.global;
    return b;
  }

 private:
  RobotId self_;
  std::uint32_t incarnation_;
  GlobalMapOptions association_;
  AssociationMemo memo_;
};

}  // namespace

std::unique_ptr<FusionBackend> MakeFusionBackend(RobotId self, std::uint32_t incarnation,
                                                 const GlobalMapOptions& options) {
  if (options.method == FusionMethod::kJoining) return std::make_unique<JoiningFusion>(self, incarnation, options);
  return std::make_unique<CloneFusion>(self, incarnation, options);
}

}  // namespace mapmesh
