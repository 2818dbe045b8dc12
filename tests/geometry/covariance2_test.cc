// The 2 x 2 covariance closed forms (common/geometry/covariance2.h) against Eigen's symmetric
// eigensolver over seeded random covariances, and at the degenerate ones.
#include "common/geometry/covariance2.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

namespace mapmesh {
namespace {

TEST(Covariance2, LargestEigenvalueIsTheSolversOverSeededCovariances) {
  std::mt19937_64 rng(20261204);
  std::uniform_real_distribution<double> angle(0.0, 6.283185307179586), scale(-4.0, 1.0);
  for (int trial = 0; trial < 2000; ++trial) {
    const double a = angle(rng), s1 = std::pow(10.0, scale(rng)), s2 = std::pow(10.0, scale(rng));
    const Eigen::Matrix2d r = Eigen::Rotation2Dd(a).toRotationMatrix();
    const Eigen::Matrix2d c = r * Eigen::Vector2d(s1 * s1, s2 * s2).asDiagonal() * r.transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(c);
    const double largest = solver.eigenvalues().maxCoeff();
    EXPECT_NEAR(LargestEigenvalue(c), largest, 1e-12 * largest + 1e-18) << c;
    EXPECT_NEAR(LargestSigma(c), std::sqrt(largest), 1e-9 * std::sqrt(largest) + 1e-12);
  }
}

TEST(Covariance2, DegenerateCovariances) {
  EXPECT_EQ(LargestEigenvalue(Eigen::Matrix2d::Zero()), 0.0);
  EXPECT_EQ(LargestSigma(Eigen::Matrix2d::Zero()), 0.0);
  Eigen::Matrix2d line;
  line << 4.0, 0.0, 0.0, 0.0;  // rank 1
  EXPECT_DOUBLE_EQ(LargestEigenvalue(line), 4.0);
  EXPECT_DOUBLE_EQ(LargestSigma(line), 2.0);
  EXPECT_DOUBLE_EQ(LargestEigenvalue(Eigen::Matrix2d::Identity() * 9.0), 9.0);  // a circle: the root is 0
  EXPECT_EQ(LargestSigma(-Eigen::Matrix2d::Identity()), 0.0);                   // no positive eigenvalue
}

}  // namespace
}  // namespace mapmesh
