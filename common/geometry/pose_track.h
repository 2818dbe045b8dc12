#pragma once
// The pose at a time along a track of time-stamped poses: the one implementation behind the
// ground-truth lookups of the feeder, the evaluation and the lab.

#include <algorithm>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"

namespace mapmesh {

// A pose at a time: one sample of a track.
struct PoseStamp {
  double t = 0.0;
  Pose2 pose;
};

// The pose at time t along `track`, whose samples are in time order: a sample's own pose at
// its stamp, Interpolate between the two samples around t, and the end samples' poses outside
// the track's span; nullopt for an empty track. stamp(sample) and pose(sample) read a sample.
template <typename Sample, typename StampOf, typename PoseOf>
std::optional<Pose2> PoseAlong(const std::vector<Sample>& track, double t, StampOf stamp, PoseOf pose) {
  if (track.empty()) return std::nullopt;
  if (t <= stamp(track.front())) return pose(track.front());
  if (t >= stamp(track.back())) return pose(track.back());
  const auto hi = std::lower_bound(track.begin(), track.end(), t,
                                   [&](const Sample& s, double v) { return stamp(s) < v; });
  if (stamp(*hi) == t) return pose(*hi);
  const auto lo = hi - 1;
  return Interpolate(pose(*lo), pose(*hi), (t - stamp(*lo)) / (stamp(*hi) - stamp(*lo)));
}

}  // namespace mapmesh
