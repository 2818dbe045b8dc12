#pragma once
// A map scored against a reference map instead of landmark truth, for data without it
// (Victoria Park): the map is aligned to the reference by geometry (map_alignment.h), then
// every landmark is matched to the nearest reference landmark within a gate. The reference is
// itself an estimate (say, the whole run as one robot), so the NEES adds its covariance.

#include <optional>
#include <random>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/merge/map_alignment.h"

namespace mapmesh {

struct ReferenceQuality {
  bool aligned = false;  // the map's frame in the reference's is known (aligned, or given); nothing else is
                         // set otherwise
  Pose2 to_reference;    // the map's frame in the reference's
  int landmarks = 0;     // in the map
  int reference_landmarks = 0;
  int matched = 0;                  // map landmarks whose nearest reference landmark (within the gate) has none nearer
  int duplicates = 0;               // map landmarks within the gate of a reference landmark another one is nearer to
  int extra = 0;                    // map landmarks with no reference landmark within the gate
  double reference_coverage = 0.0;  // share of reference landmarks matched
  double rmse_m = 0.0;              // over matched landmarks, after the alignment
  double nees_mean = 0.0;           // over matched landmarks, map and reference covariances added
};

// Signatures are ignored: the alignment and the matching use geometry only. With
// known_frame (the map's frame in the reference's, say from another map in the same frame)
// the alignment is skipped.
ReferenceQuality CompareToReference(const LandmarkMap& map, const LandmarkMap& reference, double gate_m,
                                    const AlignmentOptions& align, std::mt19937_64& rng,
                                    const std::optional<Pose2>& known_frame = std::nullopt);

}  // namespace mapmesh
