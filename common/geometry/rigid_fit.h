#pragma once
// Least-squares rigid transform between matched 2D point sets (Umeyama 1991, no scale).

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"

namespace mapmesh {

// The pose T minimising sum_i |T(src_i) - dst_i|^2. nullopt when there are fewer than two
// pairs, the sizes differ, or the source points are all (nearly) the same point.
std::optional<Pose2> FitRigid2D(const std::vector<Eigen::Vector2d>& src,
                                const std::vector<Eigen::Vector2d>& dst);

}  // namespace mapmesh
