#include "common/map/landmark_map.h"

#include <algorithm>
#include <cmath>

namespace mapmesh {

const Landmark* LandmarkMap::Find(std::uint32_t id) const {
  auto it = std::find_if(landmarks.begin(), landmarks.end(), [id](const Landmark& l) { return l.id == id; });
  return it == landmarks.end() ? nullptr : &*it;
}

bool IsValidCovariance(const Eigen::Matrix2d& cov) {
  if (!cov.allFinite()) return false;
  const double scale = std::max({std::abs(cov(0, 0)), std::abs(cov(1, 1)), 1e-300});
  if (std::abs(cov(0, 1) - cov(1, 0)) > 1e-9 * scale) return false;
  // A symmetric 2x2 matrix is PSD iff both diagonal entries and the determinant are >= 0.
  const double det = cov(0, 0) * cov(1, 1) - cov(0, 1) * cov(1, 0);
  return cov(0, 0) >= 0.0 && cov(1, 1) >= 0.0 && det >= -1e-12 * scale * scale;
}

Eigen::Vector2d Centroid(const LandmarkMap& m) {
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  for (const Landmark& l : m.landmarks) c += l.mean;
  return m.empty() ? c : Eigen::Vector2d(c / static_cast<double>(m.size()));
}

LandmarkMap TransformMap(const LandmarkMap& map, const Pose2& pose) {
  LandmarkMap out = map;
  const PoseMap2 t(pose);
  const Eigen::Matrix2d r = t.Rotation();
  for (Landmark& l : out.landmarks) {
    l.mean = t.Apply(l.mean);
    l.cov = r * l.cov * r.transpose();
  }
  return out;
}

LandmarkMap WithoutSignatures(LandmarkMap map) {
  for (Landmark& l : map.landmarks) l.signature = -1;
  return map;
}

}  // namespace mapmesh
