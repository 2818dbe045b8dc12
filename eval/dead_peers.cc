#include "eval/dead_peers.h"

#include <random>
#include <set>

#include "common/merge/map_alignment.h"
#include "common/metrics/landmark_metrics.h"
#include "common/metrics/trajectory_metrics.h"
#include "common/options/exchange_options.h"

namespace mapmesh {
namespace {

std::set<int> TrueIds(const LandmarkMap& map, const Pose2& origin, const std::vector<Eigen::Vector2d>& truth,
                      double gate_m) {
  std::set<int> ids;
  for (int i : MatchToTruth(TransformMap(map, origin), truth, gate_m)) {
    if (i >= 0) ids.insert(i);
  }
  return ids;
}

}  // namespace

HeldFromPeer CheckHeld(const LandmarkMap& own_local, const LandmarkMap& own_global, const Pose2& own_origin,
                       const LandmarkMap& peer_map, const Pose2& peer_origin, const std::vector<Eigen::Vector2d>& truth,
                       double gate_m) {
  HeldFromPeer h;
  const LandmarkMap theirs_alone = WithoutSignatures(peer_map);
  const Pose2 true_to_own = own_origin.Inverse() * peer_origin;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const Landmark& l : theirs_alone.landmarks) centroid += l.mean;
  if (!theirs_alone.empty()) centroid /= static_cast<double>(theirs_alone.size());
  for (int k = 0; k < kAlignTries; ++k) {
    std::mt19937_64 rng(1000 + k);
    const AlignmentResult a = AlignMaps(own_local, theirs_alone, ExchangeAlignment(), rng);
    const TransformError e = CompareTransforms(a.transform, true_to_own, centroid);
    h.aligned_tries += a.accepted() && e.translation_m <= 1.0 && e.rotation_rad <= DegToRad(2.0) ? 1 : 0;
  }
  const AlignmentResult r = VerifyAlignment(own_local, theirs_alone, true_to_own, ExchangeAlignment());
  h.overlaps = r.accepted();
  h.verdict = ToString(r.verdict);
  h.covered = r.covered;
  h.inliers = static_cast<int>(r.inliers.size());
  const std::set<int> theirs = TrueIds(peer_map, peer_origin, truth, gate_m);
  const std::set<int> ours = TrueIds(own_global, own_origin, truth, gate_m);
  h.landmarks = static_cast<int>(theirs.size());
  for (int i : theirs) h.held += ours.count(i) ? 1 : 0;
  return h;
}

}  // namespace mapmesh
