#pragma once
// Closed forms on 2 x 2 covariances, the one copy of each (alignment, fusion and the local
// filter's shape figure use them). Pure.

#include <Eigen/Core>
#include <Eigen/LU>  // determinant()
#include <algorithm>
#include <cmath>

namespace mapmesh {

// The largest eigenvalue of a symmetric 2 x 2 matrix c: tr/2 + sqrt(tr^2/4 - det), the root's
// argument clamped at 0 (it is >= 0 for a symmetric c but for rounding).
inline double LargestEigenvalue(const Eigen::Matrix2d& c) {
  const double tr = c.trace(), det = c.determinant();
  return 0.5 * tr + std::sqrt(std::max(0.0, 0.25 * tr * tr - det));
}

// Its square root (0 for a matrix with no positive eigenvalue): the largest standard deviation
// of the covariance along any direction.
inline double LargestSigma(const Eigen::Matrix2d& c) { return std::sqrt(std::max(0.0, LargestEigenvalue(c))); }

}  // namespace mapmesh
