#include "common/map/map_limits.h"

#include <cmath>

namespace mapmesh {
namespace {

// The smaller eigenvalue of a symmetric 2x2 covariance: the variance along its most certain
// direction.
double SmallerVariance(const Eigen::Matrix2d& c) {
  const double mean = 0.5 * (c(0, 0) + c(1, 1)), half = 0.5 * (c(0, 0) - c(1, 1));
  return mean - std::sqrt(half * half + c(0, 1) * c(0, 1));
}

}  // namespace

std::string_view ToString(MapLimitViolation v) {
  switch (v) {
    case MapLimitViolation::kNone: return "none";
    case MapLimitViolation::kTooManyLandmarks: return "too_many_landmarks";
    case MapLimitViolation::kOutOfWorld: return "out_of_world";
    case MapLimitViolation::kCovarianceTooLarge: return "covariance_too_large";
    case MapLimitViolation::kCovarianceTooSmall: return "covariance_too_small";
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
  const double min_var = limits.min_sigma_m * limits.min_sigma_m;
  for (const Landmark& l : map.landmarks) {
    if (!(SmallerVariance(l.cov) >= min_var)) return MapLimitViolation::kCovarianceTooSmall;
  }
  return MapLimitViolation::kNone;
}

MapLimitViolation CheckSubmapLimits(const WireSubmap& submap, const MapLimits& limits) {
  const Eigen::Index n = static_cast<Eigen::Index>(submap.keys.size());
  if (submap.keys.size() > limits.max_landmarks) return MapLimitViolation::kTooManyLandmarks;
  for (Eigen::Index i = 0; i <= n; ++i) {  // the end pose, then each landmark
    const Eigen::Index at = i == 0 ? 0 : 1 + 2 * i;
    if (!(std::abs(submap.x(at)) <= limits.world_radius_m && std::abs(submap.x(at + 1)) <= limits.world_radius_m)) {
      return MapLimitViolation::kOutOfWorld;
    }
  }
  // Variances are the squared norms of l's rows (p = l l^T).
  const double max_var = limits.max_sigma_m * limits.max_sigma_m;
  for (Eigen::Index i = 0; i < 3 + 2 * n; ++i) {
    if (i == 2) continue;  // the end heading is an angle
    if (!(submap.l.row(i).squaredNorm() <= max_var)) return MapLimitViolation::kCovarianceTooLarge;
  }
  const double min_var = limits.min_sigma_m * limits.min_sigma_m;
  for (Eigen::Index i = 0; i < n; ++i) {  // each landmark's 2x2 block of l l^T
    const auto rows = submap.l.middleRows(3 + 2 * i, 2);
    if (!(SmallerVariance(rows * rows.transpose()) >= min_var)) return MapLimitViolation::kCovarianceTooSmall;
  }
  return MapLimitViolation::kNone;
}

}  // namespace mapmesh
