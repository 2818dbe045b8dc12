#include "agent/fusion_backend.h"

#include <algorithm>

#include "common/merge/map_joining.h"
#include "common/merge/submap_network.h"

namespace mapmesh {
namespace {

// The cloned global map (thesis 2.3.2): each source's landmarks associated with the map's and
// fused by Covariance Intersection (or the estimator options.method names).
class CloneFusion : public FusionBackend {
 public:
  CloneFusion(RobotId self, std::uint32_t incarnation, const GlobalMapOptions& options)
      : self_(self), incarnation_(incarnation), options_(options) {}
  Built Build(const LandmarkMap& own_local, const std::vector<MapSource>& sources, const std::vector<MapSource>& direct,
              const SubmapInputs&) override {
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
  Built Build(const LandmarkMap& own_local, const std::vector<MapSource>&, const std::vector<MapSource>& direct,
              const SubmapInputs& submaps) override {
    const GlobalMap associated = BuildGlobalMap(own_local, self_, direct, association_, incarnation_, &memo_);
    Built b;
    if (submaps.book != nullptr && (submaps.own_open || submaps.book->ChainLength(self_, incarnation_) > 0)) {
      b.global = JoinChains(associated, direct, submaps);
    } else {
      b.global = JoinMaps(own_local, self_, incarnation_, direct, associated);
    }
    b.published = b.global;
    b.joining = report_;
    return b;
  }

 private:
  // The submap chains joined (submap_network.h): the own chain (closed submaps, then the open
  // one) in the own frame, and each aligned peer's (closed, then its latest open one) from its
  // alignment, the association from the CI build's groups. Each landmark a chain holds gets the
  // joint estimate; one no chain holds keeps the CI build's.
  GlobalMap JoinChains(const GlobalMap& associated, const std::vector<MapSource>& direct, const SubmapInputs& submaps) {
    const SubmapBook& book = *submaps.book;
    auto chain = [&](RobotId robot, std::uint32_t incarnation, const Pose2& origin) {
      ChainInput c{robot, incarnation, {}, origin};
      const std::uint32_t n = book.ChainLength(robot, incarnation);
      for (std::uint32_t i = 0; i < n; ++i) c.submaps.push_back(book.Find({robot, incarnation, i}));
      return c;
    };
    std::vector<ChainInput> chains = {chain(self_, incarnation_, Pose2{})};
    if (submaps.own_open && submaps.own_open->id.index == chains[0].submaps.size()) {
      chains[0].submaps.push_back(submaps.own_open);  // it continues the chain (none is missing before it)
    }
    for (const MapSource& s : direct) {
      ChainInput c = chain(s.robot, s.incarnation, s.to_own);
      if (submaps.peers_open != nullptr) {
        const auto open = submaps.peers_open->find({s.robot, s.incarnation});
        if (open != submaps.peers_open->end() && open->second.id.index == c.submaps.size()) {
          c.submaps.push_back(&open->second);
        }
      }
      if (!c.submaps.empty()) chains.push_back(std::move(c));
    }
    std::map<LandmarkRef, int> groups;
    for (std::size_t g = 0; g < associated.origins.size(); ++g) {
      for (const LandmarkOrigin& o : associated.origins[g])
        groups[{o.robot, o.incarnation, o.id}] = static_cast<int>(g);
    }
    // Each chain starts where the last solve left it: the chains change little from one period
    // to the next.
    for (ChainInput& c : chains) {
      const auto it = last_frames_.find({c.robot, c.incarnation});
      if (it != last_frames_.end()) c.start_frames = it->second;
    }
    const NetworkResult r = JoinSubmapNetwork(chains, groups);
    if (r.solved) {
      last_frames_.clear();
      for (std::size_t i = 0; i < chains.size(); ++i) {
        if (r.joined[i]) last_frames_[{chains[i].robot, chains[i].incarnation}] = r.frames[i];
      }
    }
    report_.chains = static_cast<int>(chains.size());
    report_.chains_joined = static_cast<int>(std::count(r.joined.begin(), r.joined.end(), true));
    report_.submaps = r.submaps;
    report_.iterations = r.iterations;
    report_.converged = r.converged;
    report_.solved = r.solved;
    report_.ties = r.ties;
    report_.ties_dropped = r.ties_dropped;
    ++report_.solves;
    if (!r.solved) return associated;
    GlobalMap out = associated;
    for (std::size_t g = 0; g < out.map.landmarks.size(); ++g) {
      const NetworkLandmark* l = r.OfGroup(static_cast<int>(g));
      if (l == nullptr) continue;
      out.map.landmarks[g].mean = l->mean;
      out.map.landmarks[g].cov = l->cov;
    }
    return out;
  }

  RobotId self_;
  std::uint32_t incarnation_;
  GlobalMapOptions association_;
  AssociationMemo memo_;
  JoiningReport report_;
  // The last solve's frames per chain: where the next one starts.
  std::map<std::pair<RobotId, std::uint32_t>, std::vector<Pose2>> last_frames_;
};

}  // namespace

std::unique_ptr<FusionBackend> MakeFusionBackend(RobotId self, std::uint32_t incarnation,
                                                 const GlobalMapOptions& options) {
  if (options.method == FusionMethod::kJoining) return std::make_unique<JoiningFusion>(self, incarnation, options);
  return std::make_unique<CloneFusion>(self, incarnation, options);
}

}  // namespace mapmesh
