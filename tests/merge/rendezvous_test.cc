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

// Sightings of a peer robot moving through its own frame, seen from the own frame's robot:
// each one pairs where the observer placed it (own frame) with where the peer's estimate puts
// it (peer frame), both drawn with the noise their covariances state.
std::vector<SightingPair> Sightings(const Pose2& peer_to_own, int n, std::mt19937_64& rng, double noise = 1.0) {
  std::normal_distribution<double> g(0, 1);
  const Eigen::Matrix3d observer_cov = Eigen::Vector3d(0.02, 0.02, 0.0004).asDiagonal();
  const Eigen::Matrix2d peer_cov = Eigen::Vector2d(0.03, 0.01).asDiagonal();
  const double sr = 0.05, sb = 0.01;
  std::vector<SightingPair> out;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector2d peer_true(0.7 * k, 2.0 * std::sin(0.4 * k));  // in the peer's frame
    const Eigen::Vector2d in_own = peer_to_own.Apply(peer_true);
    const Pose2 observer{in_own.x() - 3.0, in_own.y() + 1.0, 0.3};
    const Eigen::Vector2d rel = observer.Inverse().Apply(in_own);
    // The observer's estimated pose and the measurement, each off by its stated noise.
    const Pose2 observed{observer.x + noise * std::sqrt(0.02) * g(rng), observer.y + noise * std::sqrt(0.02) * g(rng),
                         observer.theta + noise * 0.02 * g(rng)};
    const double range = rel.norm() + noise * sr * g(rng), bearing = std::atan2(rel.y(), rel.x()) + noise * sb * g(rng);
    SightingPair p;
    p.stamp = k;
    p.own = *SightedPosition(observed, observer_cov, range, bearing, sr, sb);
    p.peer.mean = peer_true + noise * Eigen::Vector2d(std::sqrt(0.03) * g(rng), 0.1 * g(rng));
    p.peer.cov = peer_cov;
    out.push_back(p);
  }
  return out;
}

TEST(SightedPosition, CovarianceIsTheFirstOrderPropagation) {
  const Pose2 observer{1, 2, 0.7};
  const Eigen::Matrix3d cov = (Eigen::Matrix3d() << 0.04, 0.01, 0.002, 0.01, 0.03, -0.001, 0.002, -0.001, 0.005)
                                  .finished();
  const double range = 4.0, bearing = -0.6, sr = 0.1, sb = 0.03;
  const auto p = SightedPosition(observer, cov, range, bearing, sr, sb);
  ASSERT_TRUE(p.has_value());
  EXPECT_NEAR((p->mean - observer.Apply({range * std::cos(bearing), range * std::sin(bearing)})).norm(), 0.0, 1e-12);
  // Jacobian with respect to (x, y, theta, range, bearing), numerically.
  auto f = [](const Eigen::VectorXd& s) {
    const Eigen::Vector2d m = Pose2{s(0), s(1), s(2)}.Apply({s(3) * std::cos(s(4)), s(3) * std::sin(s(4))});
    return Eigen::VectorXd(m);
  };
  Eigen::VectorXd x(5);
  x << observer.x, observer.y, observer.theta, range, bearing;
  const Eigen::MatrixXd j = testing::NumericJacobian(f, x);
  Eigen::MatrixXd in = Eigen::MatrixXd::Zero(5, 5);
  in.topLeftCorner<3, 3>() = cov;
  in(3, 3) = sr * sr;
  in(4, 4) = sb * sb;
  EXPECT_LT((p->cov - j * in * j.transpose()).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_FALSE(SightedPosition(observer, cov, range, std::nan(""), sr, sb).has_value());
  EXPECT_FALSE(SightedPosition(observer, cov, range, bearing, 0.0, sb).has_value());
}

TEST(FitRendezvous, RecoversTheTransformConsistentlyFromNoisySightings) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-30, 30), ua(-M_PI, M_PI);
  double nees = 0;
  const int kRuns = 300;
  for (int run = 0; run < kRuns; ++run) {
    const Pose2 truth{u(rng), u(rng), ua(rng)};
    const auto pairs = Sightings(truth, 12, rng);
    const RendezvousFit fit = FitRendezvous(pairs, {}, {});
    ASSERT_TRUE(fit.accepted()) << ToString(fit.verdict) << " run " << run;
    const Eigen::Vector3d e(fit.transform.x - truth.x, fit.transform.y - truth.y,
                            WrapAngle(fit.transform.theta - truth.theta));
    nees += e.dot(fit.cov.ldlt().solve(e));
  }
  // Covariance Intersection of the sightings is conservative for independent ones (their
  // average information, not the sum): NEES well under 3, never above.
  nees /= kRuns;
  RecordProperty("nees", std::to_string(nees));
  EXPECT_LT(nees, 3.0);
  EXPECT_GT(nees, 0.05);  // ... but not so inflated that it says nothing
}

TEST(FitRendezvous, LeavesOutASightingWithAPeerPoseFiveMetresOff) {
  std::mt19937_64 rng(12);
  const Pose2 truth{4, -7, 1.1};
  auto pairs = Sightings(truth, 10, rng);
  pairs[4].peer.mean.x() += 5.0;
  const RendezvousFit fit = FitRendezvous(pairs, {}, {});
  ASSERT_TRUE(fit.accepted()) << ToString(fit.verdict);
  EXPECT_EQ(fit.inlier_pairs, 9);
  EXPECT_LT(std::hypot(fit.transform.x - truth.x, fit.transform.y - truth.y), 0.3);
  EXPECT_LT(std::abs(WrapAngle(fit.transform.theta - truth.theta)), 0.03);
}

TEST(FitRendezvous, RefusesWhatDoesNotFixTheTransform) {
  std::mt19937_64 rng(13);
  const Pose2 truth{4, -7, 1.1};
  auto pairs = Sightings(truth, 10, rng);
  EXPECT_EQ(FitRendezvous(std::span(pairs).first(2), {}, {}).verdict, RendezvousVerdict::kTooFewSightings);
  // All from one spot in the peer's frame: the rotation is free.
  auto still = pairs;
  for (auto& p : still) p.peer.mean = pairs[0].peer.mean;
  EXPECT_EQ(FitRendezvous(still, {}, {}).verdict, RendezvousVerdict::kNoBaseline);
  // Half of them 5 m off in different directions: the other half still decides ...
  auto wild = pairs;
  for (std::size_t i = 0; i < wild.size(); i += 2)
    wild[i].peer.mean += Eigen::Vector2d(5.0 * std::cos(i), 5.0 * std::sin(i));
  const RendezvousFit half = FitRendezvous(wild, {}, {});
  ASSERT_TRUE(half.accepted()) << ToString(half.verdict);
  EXPECT_EQ(half.inlier_pairs, 5);
  EXPECT_LT(std::hypot(half.transform.x - truth.x, half.transform.y - truth.y), 0.3);
  // ... but with six of ten off, no transform has the support of half of them.
  wild = pairs;
  for (std::size_t i = 0; i < wild.size(); ++i) {
    if (i % 3 != 0) wild[i].peer.mean += Eigen::Vector2d(5.0 * std::cos(i), 5.0 * std::sin(i));
  }
  const RendezvousVerdict v = FitRendezvous(wild, {}, {}).verdict;
  EXPECT_TRUE(v == RendezvousVerdict::kTooFewInliers || v == RendezvousVerdict::kResidualsTooLarge) << ToString(v);
  // Covariances that claim ten times the precision: the residuals give them away.
  auto overconfident = pairs;
  for (auto& p : overconfident) {
    p.own.cov /= 400.0;
    p.peer.cov /= 400.0;
  }
  const RendezvousVerdict o = FitRendezvous(overconfident, {}, {}).verdict;
  EXPECT_TRUE(o == RendezvousVerdict::kTooFewInliers || o == RendezvousVerdict::kResidualsTooLarge) << ToString(o);
}

TEST(FitRendezvous, OneMutualRendezvousFixesTheRotationOfSightingsFromOneSpot) {
  const Pose2 truth{3, -4, 0.8};
  const RendezvousInput in = Scene(truth, {2, 1, 0.4}, {-1, 3, -2.0});
  const RendezvousResult m = *RendezvousAlign(in);
  SightingPair p;
  p.peer.mean = {-1, 3};
  p.peer.cov = in.cov2.topLeftCorner<2, 2>();
  p.own.mean = truth.Apply(p.peer.mean);
  p.own.cov = Eigen::Matrix2d::Identity() * 0.01;
  const std::vector<SightingPair> one{p};
  const std::vector<RendezvousResult> mutual{m};
  const RendezvousFit fit = FitRendezvous(one, mutual, {});
  ASSERT_TRUE(fit.accepted()) << ToString(fit.verdict);
  EXPECT_EQ(fit.inlier_mutual, 1);
  EXPECT_NEAR(fit.transform.x, truth.x, 1e-6);
  EXPECT_NEAR(WrapAngle(fit.transform.theta - truth.theta), 0.0, 1e-6);
}

}  // namespace
}  // namespace mapmesh
