#pragma once
// The cloned global map (thesis 2.3.2, ALGORITHMS.md 5): a robot never fuses others'
// information into its own SLAM state. Its global map is rebuilt, whenever something changed,
// from a clone of its local map plus the latest map of every aligned source (a peer's local
// map, or a peer's global map when maps are relayed), each moved into the own frame with the
// alignment's covariance propagated into every landmark's covariance.
//
// A source's landmarks are associated to the global landmarks by a Mahalanobis gate on the
// combined covariance; where a gate admits more than one pairing, the connected group of
// candidates is resolved by joint compatibility (JCBB, Neira & Tardos 2001), whose joint test
// includes the correlation that the shared alignment error puts between a source's
// landmarks. Each global landmark then fuses all its inputs at once with the chosen estimator
// (fusion.h); unmatched landmarks are appended.
//
// Rebuilding from the latest snapshots, rather than accumulating over time, keeps the same
// information from being counted again at every exchange. Relaying breaks independence
// anyway: a peer's global map may already contain this robot's own landmarks, or a third
// robot's that another source also brings. Covariance Intersection stays consistent under
// any such correlation; information fusion counts the shared information twice and becomes
// overconfident, more so the more often maps have been exchanged; Maximum Likelihood ignores
// covariances altogether. docs/EXPERIMENTS.md (fusion) gives the figures.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <span>
#include <string_view>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/merge/fusion.h"
#include "common/types/messages.h"

namespace mapmesh {

// One contributor to the global map.
struct MapSource {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;                         // which start of the robot's process (its frame)
  LandmarkMap map;                                       // in the source's own frame
  Pose2 to_own;                                          // maps the source's frame into the own frame
  Eigen::Matrix3d to_own_cov = Eigen::Matrix3d::Zero();  // of (x, y, theta) of to_own
  bool relayed = false;  // map is the source's global map (a relay): its ids are that map's, not its robot's
};

struct GlobalMapOptions {
  FusionMethod method = FusionMethod::kCiConstant;  // agent.fusion
  double gate_probability = 0.999;                  // individual and joint compatibility (chi-square); a missed true
                                                    // pair duplicates a landmark, so the gate is wide and JCBB
                                                    // settles what it lets through
  int max_jcbb_landmarks = 10;                      // larger ambiguous groups are resolved greedily (closest first)
  long max_jcbb_nodes = 20000;                      // per group

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md).
  template <typename Reader>
  void Read(Reader& r) {
    r.GetChoice("fusion", method, kFusionMethods);
  }
};

// A source landmark that went into a global landmark.
struct LandmarkOrigin {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  std::uint32_t id = 0;  // the landmark's id in its source map
  bool relayed = false;  // the source map was a relayed global map (MapSource::relayed)
};

struct GlobalMapStats {
  int local = 0;               // local landmarks cloned
  int sources = 0;             // sources used
  int rejected_sources = 0;    // with an invalid transform covariance
  int associated = 0;          // source landmarks fused into an existing global landmark
  int appended = 0;            // source landmarks that started a global landmark
  int rejected_landmarks = 0;  // invalid landmarks (local or source): never fused
  int non_finite_mean = 0, invalid_covariance = 0, singular_covariance = 0;  // ... by reason
  int ambiguous_groups = 0;                                                  // candidate groups resolved by JCBB
  int greedy_groups = 0;  // ... too large for JCBB, resolved closest first
};

struct GlobalMap {
  LandmarkMap map;                                   // in the own frame; ids are indices; a landmark keeps a
                                                     // signature its inputs agree on (unknown ones aside)
  std::vector<std::vector<LandmarkOrigin>> origins;  // per global landmark, its inputs (first: the anchor)
  GlobalMapStats stats;
};

// What one build resolved by joint compatibility, for the next build of the same map: an
// ambiguous group whose members (source landmarks, by origin) have the same candidate clusters
// (by their anchors' origins) as in the previous build keeps the pairing chosen then, as long
// as that pairing is still jointly compatible; only new or changed groups are searched. Maps
// rebuilt every period from mostly unchanged sources then cost a gate pass, not a search.
class AssociationMemo {
 public:
  using Key = std::vector<std::uint32_t>;  // the group: members and their candidates, by origin
  struct Stats {
    int reused = 0;    // groups that kept the previous build's pairing
    int searched = 0;  // groups searched (new, changed, or no longer compatible)
  };
  // Starts a build: what the previous one kept can be looked up, and only that.
  void BeginBuild();
  // The pairing the previous build chose for this group (per member, the index of its
  // candidate in key order, or -1), or null.
  const std::vector<int>* Previous(const Key& group) const;
  // Keeps this build's pairing of the group for the next build.
  void Keep(Key group, std::vector<int> choice, bool reused);
  const Stats& stats() const { return stats_; }  // of the last build

 private:
  std::map<Key, std::vector<int>> previous_, current_;
  Stats stats_;
};

// Builds the global map of robot `self` from its local map and the sources (taken in the
// order given; pass them sorted for reproducible results). With a memo (kept from the previous
// build of this map), unchanged ambiguous groups keep their pairing (AssociationMemo).
GlobalMap BuildGlobalMap(const LandmarkMap& local, RobotId self, std::span<const MapSource> sources,
                         const GlobalMapOptions& options, std::uint32_t self_incarnation = 0,
                         AssociationMemo* memo = nullptr);

// The source's landmark moved into the own frame: mean T(m), covariance R C R^T + J P J^T,
// with J the Jacobian of T(m) with respect to the transform (x, y, theta).
Landmark TransformLandmark(const Landmark& l, const Pose2& t, const Eigen::Matrix3d& t_cov);
// The same with t's sine and cosine evaluated once (for a whole map), and the Jacobian of the
// mean with respect to t when j_pose is given.
Landmark TransformLandmark(const Landmark& l, const PoseMap2& t, const Eigen::Matrix3d& t_cov,
                           Eigen::Matrix<double, 2, 3>* j_pose);

}  // namespace mapmesh
