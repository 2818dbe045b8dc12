#pragma once
// How well an agent placed its peers' maps, judged against the truth of the run: the one
// implementation behind mapmesh-eval (a run directory) and the lab's in-process bus.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>

#include "common/geometry/pose2.h"
#include "common/metrics/trajectory_metrics.h"
#include "common/types/messages.h"

namespace mapmesh {

// A peer map as its holder placed it.
struct PlacedPeer {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  Pose2 to_own;                                        // the peer's map frame in the holder's
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();  // of the peer's map, in the peer's frame
  double origin_stamp = 0.0;                           // when the peer's map frame was fixed
};

// The error of one placement. `from_start` compares with the true transform between the poses
// at which both frames were fixed; `from_fit` with the transform between the frames the two
// maps are really in (their rigid fits to the landmark truth), which a map's own drift does not
// count against the alignment. Translation errors are taken at the peer map's centroid.
struct PlacementError {
  TransformError from_start;
  std::optional<TransformError> from_fit;
};

// The true pose of a robot at a scenario time, nullopt when unknown.
using TruePoseAt = std::function<std::optional<Pose2>(RobotId robot, double t)>;

// Scores `peer` as placed by a holder whose map frame truly is `own_origin`. own_fit and
// peer_fit are the two local maps' frames fitted to the truth (MapFrameInWorld), when known;
// from_fit needs both. nullopt when the peer's true origin is unknown.
std::optional<PlacementError> ScorePlacement(const PlacedPeer& peer, const Pose2& own_origin,
                                             const TruePoseAt& true_pose, const std::optional<Pose2>& own_fit,
                                             const std::optional<Pose2>& peer_fit);

}  // namespace mapmesh
