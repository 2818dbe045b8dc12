#include "common/merge/rendezvous.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>

#include "tests/testing/numeric_jacobian.h"

namespace mapmesh {
namespace {

// A true scene: two frames, two robots, and their noise-free mutual sightings.
RendezvousInput Scene(const Pose2& frame2_in_1, const Pose2& r1_in_1, const Pose2& r2_in_2) {
  RendezvousInput in;
  in.pose1 = r1_in_1;
  in.pose2 = r2_in_2;
  const Pose2 r2_in_1 = frame2_in_1 * r2_in_2;
  const Pose2 rel12 = r1_in_1.Inverse() * r2_in_1;  // robot 2 seen from robot 1
  const Pose2 rel21 = r2_in_1.Inverse() * r1_in_1;
  in.range12 = std::hypot(rel12.x, rel12.y);
  in.bearing12 = std::atan2(rel12.y, rel12.x);
  in.range21 = std::hypot(rel21.x, rel21.y);
  in.bearing21 = std::atan2(rel21.y, rel21.x);
  in.cov1 = Eigen::Vector3d(0.01, 0.01, 0.001).asDiagonal();
  in.cov2 = Eigen::Vector3d(0.02, 0.01, 0.002).asDiagonal();
  return in;
}

TEST(Rendezvous, RecoversTheFrameTransformFromNoiseFreeSightings) {
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-20, 20), ua(-M_PI, M_PI);
  for (int i = 0; i < 100; ++i) {
    const Pose2 truth{u(rng), u(rng), ua(rng)};
    const RendezvousInput in = Scene(truth, {u(rng), u(rng), ua(rng)}, {u(rng), u(rng), ua(rng)});
    const auto r = RendezvousAlign(in);
    ASSERT_TRUE(r.has_value());
    EXPECT_NEAR(r->transform.x, truth.x, 1e-9);
    EXPECT_NEAR(r->transform.y, truth.y, 1e-9);
    EXPECT_NEAR(WrapAngle(r->transform.theta - truth.theta), 0.0, 1e-9);
    EXPECT_NEAR(r->range_disagreement, 0.0, 1e-9);
  }
}

TEST(Rendezvous, FusesTheTwoRangesByInverseVariance) {
  RendezvousInput in = Scene({1, 2, 0.3}, {0, 0, 0}, {1, 1, 1});
  const double true_range = in.range12;
  in.range12 = true_range + 0.3;
  in.range21 = true_range - 0.1;
  in.sigma_range1 = 0.2;
  in.sigma_range2 = 0.1;
  // (r1 / 0.04 + r2 / 0.01) / (1 / 0.04 + 1 / 0.01): weights 1 : 4.
  EXPECT_NEAR(RendezvousAlign(in)->range, true_range + (0.3 + 4 * -0.1) / 5, 1e-12);
}

TEST(Rendezvous, CovarianceMatchesMonteCarlo) {
  // Sample the inputs from their stated covariances: the transform's NEES averages 3.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0, 1);
  const Pose2 truth{3, -4, 0.8};
  const RendezvousInput clean = Scene(truth, {2, 1, 0.4}, {-1, 3, -2.0});
  const Eigen::Matrix3d l1 = clean.cov1.llt().matrixL(), l2 = clean.cov2.llt().matrixL();
  double nees = 0;
  const int kN = 4000;
  for (int k = 0; k < kN; ++k) {
    RendezvousInput in = clean;
    const Eigen::Vector3d d1 = l1 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    const Eigen::Vector3d d2 = l2 * Eigen::Vector3d(n(rng), n(rng), n(rng));
    in.pose1 = {clean.pose1.x + d1(0), clean.pose1.y + d1(1), clean.pose1.theta + d1(2)};
    in.pose2 = {clean.pose2.x + d2(0), clean.pose2.y + d2(1), clean.pose2.theta + d2(2)};
    in.range12 += in.sigma_range1 * n(rng);
    in.bearing12 += in.sigma_bearing1 * n(rng);
    in.range21 += in.sigma_range2 * n(rng);
    in.bearing21 += in.sigma_bearing2 * n(rng);
    const auto r = RendezvousAlign(in);
    const Eigen::Vector3d e(r->transform.x - truth.x, r->transform.y - truth.y,
                            WrapAngle(r->transform.theta - truth.theta));
    nees += e.dot(r->cov.ldlt().solve(e));
  }
  EXPECT_NEAR(nees / kN, 3.0, 0.3);
}

TEST(Pose2Jacobians, ComposeAndInvertMatchNumericalDifferentiation) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(-5, 5), ua(-M_PI, M_PI);
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d a(u(rng), u(rng), ua(rng)), b(u(rng), u(rng), ua(rng));
    Eigen::Matrix3d ja, jb, ji;
    Compose({a(0), a(1), a(2)}, {b(0), b(1), b(2)}, &ja, &jb);
    Invert({a(0), a(1), a(2)}, &ji);
    auto fa = [&](const Eigen::VectorXd& s) {
      return Eigen::VectorXd((Pose2{s(0), s(1), s(2)} * Pose2{b(0), b(1), b(2)}).Vector());
    };
    auto fb = [&](const Eigen::VectorXd& s) {
      return Eigen::VectorXd((Pose2{a(0), a(1), a(2)} * Pose2{s(0), s(1), s(2)}).Vector());
    };
    auto fi = [&](const Eigen::VectorXd& s) { return Eigen::VectorXd(Pose2{s(0), s(1), s(2)}.Inverse().Vector()); };
    EXPECT_LT((ja - testing::NumericJacobian(fa, a, 1e-6, {2})).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LT((jb - testing::NumericJacobian(fb, b, 1e-6, {2})).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LT((ji - testing::NumericJacobian(fi, a, 1e-6, {2})).cwiseAbs().maxCoeff(), 1e-7);
  }
}

TEST(Rendezvous, RejectsNonFiniteInput) {
  RendezvousInput in = Scene({1, 2, 0.3}, {0, 0, 0}, {1, 1, 1});
  in.bearing21 = std::nan("");
  EXPECT_FALSE(RendezvousAlign(in).has_value());
  in = Scene({1, 2, 0.3}, {0, 0, 0}, {1, 1, 1});
  in.sigma_range2 = 0.0;
  EXPECT_FALSE(RendezvousAlign(in).has_value());
}

}  // namespace
}  // namespace mapmesh
