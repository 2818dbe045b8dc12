#include "common/slam/iekf_slam.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <random>

#include "common/config/scenario.h"
#include "common/slam/ekf_slam.h"
#include "common/slam/observation_model.h"
#include "tests/testing/feed_filters.h"
#include "tests/testing/filter_noise.h"

namespace mapmesh {
namespace {

using testing::TestFilterNoise;

// A filter that has moved and mapped landmarks around it, with a full-rank covariance.
IekfSlam Mapped(std::mt19937_64& rng, int landmarks) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  IekfSlam f(TestFilterNoise());
  f.Predict({0.4 + 0.2 * u(rng), 0.5 * u(rng), 0.0}, 0.7);
  for (int i = 0; i < landmarks; ++i) f.Add(static_cast<LandmarkId>(i), {2.0 + 3.0 * (u(rng) + 1.0), 1.5 * u(rng)});
  f.Predict({0.5, 0.3 * u(rng), 0.0}, 1.3);
  return f;
}

// The sighting's Jacobian in the invariant error against central differences of X <- exp(e) X.
TEST(IekfSlam, SightingJacobianMatchesNumericalDifferentiation) {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const IekfSlam f = Mapped(rng, 4);
    const Eigen::Index n = f.state().size();
    for (int slot = 0; slot < 4; ++slot) {
      const Eigen::MatrixXd h = f.SightingJacobian(slot);
      Eigen::MatrixXd numeric(2, n);
      const double step = 1e-6;
      for (Eigen::Index j = 0; j < n; ++j) {
        IekfSlam plus = f, minus = f;
        const Eigen::VectorXd e = Eigen::VectorXd::Unit(n, j) * step;
        plus.Retract(e);
        minus.Retract(-e);
        const auto id = static_cast<LandmarkId>(slot);
        Eigen::Vector2d d = ObserveRangeBearing(plus.robot(), plus.Mean(id)) -
                            ObserveRangeBearing(minus.robot(), minus.Mean(id));
        d(1) = WrapAngle(d(1));
        numeric.col(j) = d / (2 * step);
      }
      EXPECT_LT((h - numeric).cwiseAbs().maxCoeff(), 1e-6) << "trial " << trial << " slot " << slot;
    }
  }
}

// The three directions no sighting observes: a global shift (rho_p = rho_l = t) and a global
// turn (omega alone), the same at every estimate.
Eigen::MatrixXd Unobservable(Eigen::Index n) {
  Eigen::MatrixXd u = Eigen::MatrixXd::Zero(n, 3);
  for (Eigen::Index r = 0; r < n; r += (r == 0 ? 3 : 2)) u.block<2, 2>(r, 0).setIdentity();
  u(2, 2) = 1.0;
  return u;
}

TEST(IekfSlam, NoSightingObservesAGlobalShiftOrTurnAtAnyEstimate) {
  std::mt19937_64 rng(4);
  for (int trial = 0; trial < 20; ++trial) {
    const IekfSlam f = Mapped(rng, 5);
    for (int slot = 0; slot < 5; ++slot) {
      EXPECT_LT((f.SightingJacobian(slot) * Unobservable(f.state().size())).cwiseAbs().maxCoeff(), 1e-12);
    }
  }
}

// What that buys (the EKF's own test, EkfSlamFirstEstimates.UnobservableDirectionsGainNoInformation):
// over a run of predictions, updates and new landmarks the information along those directions
// never grows, with no first-estimates bookkeeping.
TEST(IekfSlam, UnobservableDirectionsGainNoInformation) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n01(0.0, 1.0);
  const std::vector<Eigen::Vector2d> world{{4, 1}, {6, -3}, {2, 5}, {-3, 4}, {-5, -2}, {1, -6}, {7, 4}, {-6, 3}};
  IekfSlam f(TestFilterNoise());
  auto information = [&] {
    const Eigen::MatrixXd n = Unobservable(f.state().size());
    const Eigen::MatrixXd p = f.invariant_cov() + 1e-12 * Eigen::MatrixXd::Identity(n.rows(), n.rows());
    return Eigen::MatrixXd(n.transpose() * p.ldlt().solve(n));
  };
  // A full-rank start: some motion before the first sighting.
  f.Predict({0.3, 0.25, 0.0}, 2.0);
  Pose2 truth = UnicycleMotion({}, {0.3, 0.25}, 2.0);
  double largest_gain = 0.0;
  std::vector<bool> mapped(world.size(), false);
  for (int step = 1; step <= 300; ++step) {
    const UnicycleControl u{0.3, 0.25};
    truth = UnicycleMotion(truth, u, 0.1);
    Eigen::MatrixXd before = information();
    f.Predict({u.v_mps + 0.03 * n01(rng), u.w_radps + 0.05 * n01(rng), 0.0}, 0.1);
    Eigen::MatrixXd after = information();
    largest_gain = std::max(largest_gain, (after - before).eigenvalues().real().maxCoeff() / before.norm());
    if (step % 5 != 0) continue;
    std::vector<std::pair<LandmarkId, Eigen::Vector2d>> seen, fresh;
    for (std::size_t i = 0; i < world.size(); ++i) {
      Eigen::Vector2d z = ObserveRangeBearing(truth, world[i]);
      if (z(0) > 8.0) continue;
      z += Eigen::Vector2d(0.05 * n01(rng), DegToRad(1.0) * n01(rng));
      (mapped[i] ? seen : fresh).emplace_back(static_cast<LandmarkId>(i), z);
    }
    before = information();
    ASSERT_TRUE(f.Update(seen));
    after = information();
    largest_gain = std::max(largest_gain, (after - before).eigenvalues().real().maxCoeff() / before.norm());
    for (const auto& [id, z] : fresh) {
      before = information();
      f.Add(id, z);
      mapped[id] = true;
      after = information();
      largest_gain = std::max(largest_gain, (after - before).eigenvalues().real().maxCoeff() / before.norm());
    }
  }
  EXPECT_EQ(f.size(), world.size());
  EXPECT_LT(largest_gain, 1e-7);
}

// With small errors the invariant filter and the EKF linearise alike: on a seeded random world
// (known association) their maps agree to millimetres and their standard-coordinate
// covariances to a few per cent, and both hold every landmark.
TEST(IekfSlam, AgreesWithTheEkfWhenItsErrorsAreSmall) {
  const Scenario sc = ParseScenario(R"(seed: 6
duration_s: 60
world: {landmarks: {generator: {count: 80, area_m: [0, 0, 40, 40], min_spacing_m: 1.5}}}
robots:
  count: 1
  defaults: {preset: thesis, path: {type: random, count: 4}, sensor: {signatures: true}}
)",
                                    "iekf.yaml");
  FilterNoise noise = TestFilterNoise();
  EkfSlam ekf(noise);
  IekfSlam iekf(noise);
  testing::FeedFilters(sc, {&ekf, &iekf});
  ASSERT_GT(ekf.size(), 10u);
  ASSERT_EQ(ekf.size(), iekf.size());
  const LandmarkMap a = ekf.Map(), b = iekf.Map();
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_LT((a.landmarks[i].mean - b.landmarks[i].mean).norm(), 0.01) << "landmark " << a.landmarks[i].id;
    const double ta = a.landmarks[i].cov.trace(), tb = b.landmarks[i].cov.trace();
    EXPECT_NEAR(tb / ta, 1.0, 0.1) << "landmark " << a.landmarks[i].id;
  }
  EXPECT_LT((ekf.robot().Vector() - iekf.robot().Vector()).norm(), 0.01);
}

// The standard-coordinate covariances the agent reads are one matrix, seen in parts: the joint
// block, the cross block of two landmarks and the map's marginals all come from FullState's.
TEST(IekfSlam, EveryCovarianceIsAPartOfTheFullStandardOne) {
  std::mt19937_64 rng(11);
  const IekfSlam f = Mapped(rng, 4);
  Eigen::VectorXd x;
  Eigen::MatrixXd p;
  std::vector<LandmarkId> ids;
  f.FullState(&x, &p, &ids);
  ASSERT_EQ(ids.size(), 4u);
  EXPECT_GT(p.ldlt().vectorD().minCoeff(), 0.0);
  EXPECT_LT((f.JointCov(ids) - p).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((f.robot_cov() - p.topLeftCorner<3, 3>()).cwiseAbs().maxCoeff(), 1e-15);
  const LandmarkMap map = f.Map();
  for (int a = 0; a < 4; ++a) {
    EXPECT_LT((map.landmarks[a].cov - p.block<2, 2>(3 + 2 * a, 3 + 2 * a)).cwiseAbs().maxCoeff(), 1e-15);
    for (int b = 0; b < 4; ++b) {
      EXPECT_LT((f.CrossCov(ids[a], ids[b]) - p.block<2, 2>(3 + 2 * a, 3 + 2 * b)).cwiseAbs().maxCoeff(), 1e-15);
    }
  }
}

}  // namespace
}  // namespace mapmesh
