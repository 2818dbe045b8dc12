#pragma once
// What a receiver is willing to take from a peer: bounds on a map's size, extent and
// uncertainty, checked before any work is spent on it (alignment, fusion). The wire codec has
// its own, wider bounds (map_codec.h); these are the agent's configured ones.

#include <cstddef>
#include <string_view>

#include "common/map/landmark_map.h"
#include "common/map/map_codec.h"
#include "common/map/submap_codec.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

struct MapLimits {
  std::size_t max_landmarks = 10000;  // agent.max_peer_landmarks: landmarks in one map
  double world_radius_m = 5000.0;     // agent.world_radius_m: |x| and |y| of every landmark in its map's frame
  double max_sigma_m = 500.0;         // agent.max_landmark_sigma_m: standard deviation of a landmark along either axis
  // agent.min_landmark_sigma_m: a landmark's standard deviation along its most certain direction
  // (issue R3: 1e-30 m made a peer's landmark outweigh everything). 1 um: no range sensor's
  // reading (1 mm or more) gets there in fewer than 10^6 readings of one landmark.
  double min_sigma_m = 1e-6;

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md), within the codec's bounds.
  template <typename Reader>
  void Read(Reader& r) {
    int n = static_cast<int>(max_landmarks);
    r.GetInRange("max_peer_landmarks", n, 1, static_cast<int>(kMapCodecMaxLandmarks));
    max_landmarks = static_cast<std::size_t>(n);
    r.GetInRange("world_radius_m", world_radius_m, 1.0, kMapCodecMaxCoordinateM);
    r.GetPositiveUpTo("max_landmark_sigma_m", max_sigma_m, limits::kMaxLengthM);
    r.GetPositiveUpTo("min_landmark_sigma_m", min_sigma_m, max_sigma_m);
  }
};

// Why a map is refused; kNone when it is within the limits.
enum class MapLimitViolation { kNone = 0, kTooManyLandmarks, kOutOfWorld, kCovarianceTooLarge, kCovarianceTooSmall };

std::string_view ToString(MapLimitViolation v);

// The first limit the map exceeds, checked in the order of the enum (a decoded map is finite
// with valid covariances already).
MapLimitViolation CheckMapLimits(const LandmarkMap& map, const MapLimits& limits);
// The same for a decoded closed submap (issue J1), in its own frame: its landmarks, its end
// pose and landmarks within world_radius_m, and each position's standard deviation (a
// landmark's at least min_sigma_m along its most certain direction).
MapLimitViolation CheckSubmapLimits(const WireSubmap& submap, const MapLimits& limits);

}  // namespace mapmesh
