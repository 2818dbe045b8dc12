#pragma once
// What a receiver is willing to take from a peer: bounds on a map's size, extent and
// uncertainty, checked before any work is spent on it (alignment, fusion). The wire codec has
// its own, wider bounds (map_codec.h); these are the agent's configured ones.

#include <cstddef>
#include <string_view>

#include "common/map/landmark_map.h"

namespace mapmesh {

struct MapLimits {
  std::size_t max_landmarks = 10000;  // landmarks in one map
  double world_radius_m = 5000.0;     // |x| and |y| of every landmark in its map's frame
  double max_sigma_m = 500.0;         // standard deviation of a landmark along either axis
};

// Why a map is refused; kNone when it is within the limits.
enum class MapLimitViolation { kNone = 0, kTooManyLandmarks, kOutOfWorld, kCovarianceTooLarge };
inline constexpr int kMapLimitViolationCount = 4;

std::string_view ToString(MapLimitViolation v);

// The first limit the map exceeds, checked in the order of the enum (a decoded map is finite
// with valid covariances already).
MapLimitViolation CheckMapLimits(const LandmarkMap& map, const MapLimits& limits);

}  // namespace mapmesh
