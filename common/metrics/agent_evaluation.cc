#include "common/metrics/agent_evaluation.h"

namespace mapmesh {

std::optional<PlacementError> ScorePlacement(const PlacedPeer& peer, const Pose2& own_origin,
                                             const TruePoseAt& true_pose, const std::optional<Pose2>& own_fit,
                                             const std::optional<Pose2>& peer_fit) {
  const std::optional<Pose2> peer_origin = true_pose(peer.robot, peer.origin_stamp);
  if (!peer_origin) return std::nullopt;
  PlacementError e;
  e.from_start = CompareTransforms(peer.to_own, own_origin.Inverse() * *peer_origin, peer.centroid);
  if (own_fit && peer_fit) e.from_fit = CompareTransforms(peer.to_own, own_fit->Inverse() * *peer_fit, peer.centroid);
  return e;
}

}  // namespace mapmesh
