#include "eval/dead_peers.h"

#include <set>

#include "agent/map_exchange.h"
#include "common/merge/map_alignment.h"
#include "common/metrics/landmark_metrics.h"

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
                       const LandmarkMap& peer_map, const Pose2& peer_origin,
                       const std::vector<Eigen::Vector2d>& truth, double gate_m) {
  HeldFromPeer h;
  const AlignmentResult r =
      VerifyAlignment(own_local, WithoutSignatures(peer_map), own_origin.Inverse() * peer_origin, ExchangeAlignment());
  h.overlaps = r.accepted();
  h.verdict = ToString(r.verdict);
  const std::set<int> theirs = TrueIds(peer_map, peer_origin, truth, gate_m);
  const std::set<int> ours = TrueIds(own_global, own_origin, truth, gate_m);
  h.landmarks = static_cast<int>(theirs.size());
  for (int i : theirs) h.held += ours.count(i) ? 1 : 0;
  return h;
}

}  // namespace mapmesh
