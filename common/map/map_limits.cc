#include "common/map/map_limits.h"

#include <cmath>

namespace mapmesh {

std::string_view ToString(MapLimitViolation v) {
  switch (v) {
    case MapLimitViolation::kNone: return "none";
    case MapLimitViolation::kTooManyLandmarks: return "too_many_landmarks";
    case MapLimitViolation::kOutOfWorld: return "out_of_world";
    case MapLimitViolation::kCovarianceTooLarge: return "covariance_too_large";
  }
  return "unknown";
}

MapLimitViolation CheckMapLimits(const LandmarkMap& map, const MapLimits& limits) {
  if (map.size() > limits.max_landmarks) return MapLimitViolation::kTooManyLandmarks;
  for (const Landmark& l : map.landmarks) {
    if (!(std::abs(l.mean.x()) <= limits.world_radius_m && std::abs(l.mean.y()) <= limits.world_radius_m)) {
      return MapLimitViolation::kOutOfWorld;
    }
  }
  const double max_var = limits.max_sigma_m * limits.max_sigma_m;
  for (const Landmark& l : map.landmarks) {
    if (!(l.cov(0, 0) <= max_var && l.cov(1, 1) <= max_var)) return MapLimitViolation::kCovarianceTooLarge;
  }
  return MapLimitViolation::kNone;
}

}  // namespace mapmesh
