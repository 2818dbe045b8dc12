#pragma once
// Least-squares rigid transform between matched 2D point sets (Umeyama 1991, no scale).

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"

namespace mapmesh {

// The pose T minimising sum_i |T(src_i) - dst_i|^2. nullopt when there are fewer than two
// pairs, the sizes differ, or the source points are all (nearly) the same point.
std::optional<Pose2> FitRigid2D(const std::vector<Eigen::Vector2d>& src, const std::vector<Eigen::Vector2d>& dst);

// The same for exactly two pairs, in closed form (thesis eq. 57-59) and without allocating:
// the pose mapping src1, src2 onto dst1, dst2 in the least-squares sense (the rotation of the
// segments, the translation of their midpoints). nullopt when src1 and src2 (nearly) coincide.
std::optional<Pose2> FitRigid2D(const Eigen::Vector2d& src1, const Eigen::Vector2d& src2, const Eigen::Vector2d& dst1,
                                const Eigen::Vector2d& dst2);

}  // namespace mapmesh
