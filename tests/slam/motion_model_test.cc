#include "common/slam/motion_model.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <random>

#include "tests/testing/numeric_jacobian.h"

namespace mapmesh {
namespace {

TEST(UnicycleMotion, StraightStepFollowsEq98) {
  // x' = x + V dt cos th, y' = y + V dt sin th.
  const Pose2 p = UnicycleMotion({1.0, 2.0, M_PI / 6}, {0.3, 0.0}, 0.1);
  EXPECT_NEAR(p.x, 1.0 + 0.03 * std::cos(M_PI / 6), 1e-12);
  EXPECT_NEAR(p.y, 2.0 + 0.03 * std::sin(M_PI / 6), 1e-12);
  EXPECT_NEAR(p.theta, M_PI / 6, 1e-12);
}

TEST(UnicycleMotion, TurningStepFollowsEq99) {
  // V = 0.3, W = 0.5236, dt = 0.1 from (0, 0, 0): worked by hand.
  // x' = V/W sin(W dt) = 0.5729565 * 0.0523361 = 0.0299863
  // y' = V/W (1 - cos(W dt)) = 0.5729565 * 0.0013705 = 0.00078522
  const Pose2 p = UnicycleMotion({0.0, 0.0, 0.0}, {0.3, 0.5236}, 0.1);
  EXPECT_NEAR(p.x, 0.0299863, 1e-7);
  EXPECT_NEAR(p.y, 0.00078522, 1e-8);
  EXPECT_NEAR(p.theta, 0.05236, 1e-12);
}

TEST(UnicycleMotion, QuarterCircleEndsWhereGeometrySays) {
  // Turning at w for pi/(2w) seconds traces a quarter circle of radius v/w.
  const double v = 0.3, w = 0.5;
  const Pose2 p = UnicycleMotion({0, 0, 0}, {v, w}, M_PI / (2 * w));
  EXPECT_NEAR(p.x, v / w, 1e-12);
  EXPECT_NEAR(p.y, v / w, 1e-12);
  EXPECT_NEAR(p.theta, M_PI / 2, 1e-12);
}

TEST(UnicycleMotion, WrapsHeading) {
  const Pose2 p = UnicycleMotion({0, 0, M_PI - 0.01}, {0.0, 1.0}, 0.1);
  EXPECT_NEAR(p.theta, -M_PI + 0.09, 1e-12);
}

TEST(UnicycleMotion, ContinuousAtZeroTurnRate) {
  const Pose2 a = UnicycleMotion({1, 2, 0.3}, {0.5, 0.0}, 0.1);
  // A turn rate of 1e-9 rad/s bends a 5 cm step by about 2.5e-12 m.
  const Pose2 b = UnicycleMotion({1, 2, 0.3}, {0.5, 1e-9}, 0.1);
  EXPECT_NEAR(a.x, b.x, 1e-11);
  EXPECT_NEAR(a.y, b.y, 1e-11);
  // And eq. 99 evaluated directly at a moderate rate agrees with the stable form.
  const double v = 0.5, w = 0.01, dt = 0.1, th = 0.3;
  const Pose2 c = UnicycleMotion({1, 2, th}, {v, w}, dt);
  EXPECT_NEAR(c.x, 1 + v / w * (std::sin(th + w * dt) - std::sin(th)), 1e-12);
  EXPECT_NEAR(c.y, 2 + v / w * (std::cos(th) - std::cos(th + w * dt)), 1e-12);
}

class UnicycleJacobianTest : public ::testing::TestWithParam<int> {};

TEST_P(UnicycleJacobianTest, MatchesNumericalDifferentiation) {
  std::mt19937_64 rng(GetParam());
  std::uniform_real_distribution<double> u(-5, 5), ua(-M_PI, M_PI), uv(0.0, 1.0), uw(-1.0, 1.0);
  const double dt = 0.1;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d x(u(rng), u(rng), ua(rng));
    // Include turn rates at and near zero, where the model switches form.
    const double w = trial % 5 == 0 ? 0.0 : (trial % 5 == 1 ? 1e-7 : uw(rng));
    const Eigen::Vector2d c(uv(rng), w);
    Eigen::Matrix3d jx;
    Eigen::Matrix<double, 3, 2> ju;
    UnicycleMotion({x(0), x(1), x(2)}, {c(0), c(1)}, dt, &jx, &ju);
    auto f_pose = [&](const Eigen::VectorXd& s) {
      const Pose2 p = UnicycleMotion({s(0), s(1), s(2)}, {c(0), c(1)}, dt);
      return Eigen::VectorXd(p.Vector());
    };
    auto f_ctrl = [&](const Eigen::VectorXd& s) {
      const Pose2 p = UnicycleMotion({x(0), x(1), x(2)}, {s(0), s(1)}, dt);
      return Eigen::VectorXd(p.Vector());
    };
    const Eigen::MatrixXd njx = testing::NumericJacobian(f_pose, x, 1e-6, {2});
    const Eigen::MatrixXd nju = testing::NumericJacobian(f_ctrl, c, 1e-6, {2});
    EXPECT_LT((jx - njx).cwiseAbs().maxCoeff(), 1e-7) << "w=" << w << "\n" << jx << "\n" << njx;
    EXPECT_LT((ju - nju).cwiseAbs().maxCoeff(), 1e-7) << "w=" << w << "\n" << ju << "\n" << nju;
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, UnicycleJacobianTest, ::testing::Range(1, 6));

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

TEST(AckermannMotion, OneStepByHand) {
  // x = (1, 2, 0.3), v = 3 m/s, steering 0.1 rad, dt = 0.025 s, Victoria Park constants.
  // tan(0.1) = 0.100335; vc = 3 / (1 - 0.100335 * 0.76 / 2.83) = 3.083073
  // a sin + b cos = 3.78 * 0.295520 + 0.5 * 0.955336 = 1.594734; vc / L tan = 0.109307
  // x' = 1 + 0.025 (3.083073 * 0.955336 - 0.109307 * 1.594734) = 1.069276
  // y' = 2 + 0.025 (3.083073 * 0.295520 + 0.109307 * (3.78 * 0.955336 - 0.5 * 0.295520)) = 2.032242
  // phi' = 0.3 + 0.025 * 0.109307 = 0.302733
  const Pose2 p = AckermannMotion({1, 2, 0.3}, {3.0, 0.1}, 0.025, AckermannParams::VictoriaPark());
  EXPECT_NEAR(p.x, 1.069276, 2e-6);
  EXPECT_NEAR(p.y, 2.032242, 2e-6);
  EXPECT_NEAR(p.theta, 0.302733, 2e-6);
}

TEST(AckermannMotion, StraightAheadWithoutSteering) {
  const Pose2 p = AckermannMotion({0, 0, M_PI / 2}, {2.0, 0.0}, 0.5, {});
  EXPECT_NEAR(p.x, 0.0, 1e-12);
  EXPECT_NEAR(p.y, 1.0, 1e-12);
  EXPECT_NEAR(p.theta, M_PI / 2, 1e-12);
}

class AckermannJacobianTest : public ::testing::TestWithParam<int> {};

TEST_P(AckermannJacobianTest, MatchesNumericalDifferentiation) {
  std::mt19937_64 rng(GetParam());
  std::uniform_real_distribution<double> u(-50, 50), ua(-M_PI, M_PI), uv(0.0, 5.0), us(-0.5, 0.5);
  const AckermannParams params;
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d x(u(rng), u(rng), ua(rng));
    const Eigen::Vector2d c(uv(rng), us(rng));
    const double dt = 0.025;
    Eigen::Matrix3d jx;
    Eigen::Matrix<double, 3, 2> ju;
    AckermannMotion({x(0), x(1), x(2)}, {c(0), c(1)}, dt, params, &jx, &ju);
    auto f_pose = [&](const Eigen::VectorXd& s) {
      return Eigen::VectorXd(AckermannMotion({s(0), s(1), s(2)}, {c(0), c(1)}, dt, params).Vector());
    };
    auto f_ctrl = [&](const Eigen::VectorXd& s) {
      return Eigen::VectorXd(AckermannMotion({x(0), x(1), x(2)}, {s(0), s(1)}, dt, params).Vector());
    };
    EXPECT_LT((jx - testing::NumericJacobian(f_pose, x, 1e-6, {2})).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LT((ju - testing::NumericJacobian(f_ctrl, c, 1e-6, {2})).cwiseAbs().maxCoeff(), 1e-7);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, AckermannJacobianTest, ::testing::Range(1, 6));

// The first-estimates Jacobians (EkfState) rely on this: for both models the heading column
// of the pose Jacobian is the position change turned by 90 degrees, d(p')/d(theta) = J (p' - p).
TEST(MoveRobot, HeadingColumnIsThePositionChangeTurnedBy90Degrees) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-5, 5), ua(-M_PI, M_PI), uv(0.0, 3.0), us(-0.4, 0.4);
  MotionModel car;
  car.kind = MotionModel::Kind::kAckermann;
  for (const MotionModel& model : {MotionModel{}, car}) {
    for (int trial = 0; trial < 20; ++trial) {
      const Pose2 p{u(rng), u(rng), ua(rng)};
      const OdometryControl c{uv(rng), us(rng), us(rng)};
      Eigen::Matrix3d j;
      const Pose2 q = MoveRobot(model, p, c, 0.25, &j);
      EXPECT_NEAR(j(0, 2), -(q.y - p.y), 1e-12);
      EXPECT_NEAR(j(1, 2), q.x - p.x, 1e-12);
    }
  }
}

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

const Eigen::Matrix2d kDensity = Eigen::Vector2d(0.03 * 0.03 * 0.1, 0.05 * 0.05 * 0.1).asDiagonal();

// Straight ahead along x, the integral in closed form: along-track q_v dt, heading q_w dt,
// sideways v^2 q_w dt^3 / 3 and its covariance with the heading v q_w dt^2 / 2.
TEST(MotionNoise, StraightAheadIsTheIntegralInClosedForm) {
  const MotionModel model;
  const double v = 0.7, dt = 0.8, qv = kDensity(0, 0), qw = kDensity(1, 1);
  const Eigen::Matrix3d q = MotionNoise(model, Pose2{}, {v, 0.0, 0.0}, dt, kDensity);
  Eigen::Matrix3d expected;
  expected << qv * dt, 0, 0,                                   //
      0, v * v * qw * dt * dt * dt / 3, v * qw * dt * dt / 2,  //
      0, v * qw * dt * dt / 2, qw * dt;
  EXPECT_LT((q - expected).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_GT(q.determinant(), 0.0);  // one step's J (density / dt) J^T is singular
}

// The point: an interval integrated whole gains what its two pieces do, propagated, for any
// split, turn and heading, so the filter's uncertainty does not depend on the odometry's rate
// (the unicycle; the car's step is Euler's, whose pieces do not compose to the whole).
TEST(MotionNoise, AnIntervalGainsWhatItsPiecesDo) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const MotionModel model;
  for (int trial = 0; trial < 200; ++trial) {
    const Pose2 start{4 * u01(rng) - 2, 4 * u01(rng) - 2, 6 * u01(rng) - 3};
    const OdometryControl u{0.1 + 2 * u01(rng), 4 * u01(rng) - 2, 0.0};
    const double dt = 0.05 + 2 * u01(rng), split = dt * (0.05 + 0.9 * u01(rng));
    const Eigen::Matrix3d whole = MotionNoise(model, start, u, dt, kDensity);
    const Pose2 mid = MoveRobot(model, start, u, split);
    Eigen::Matrix3d phi;
    MoveRobot(model, mid, u, dt - split, &phi);
    const Eigen::Matrix3d pieces = phi * MotionNoise(model, start, u, split, kDensity) * phi.transpose() +
                                   MotionNoise(model, mid, u, dt - split, kDensity);
    EXPECT_LT((whole - pieces).cwiseAbs().maxCoeff(), 1e-9 * whole.cwiseAbs().maxCoeff()) << "trial " << trial;
  }
}

// As the interval shrinks it is one step's J (density / dt) J^T.
TEST(MotionNoise, ShortIntervalsAreOneStepsLinearisation) {
  for (const MotionModel::Kind kind : {MotionModel::Kind::kUnicycle, MotionModel::Kind::kAckermann}) {
    MotionModel model;
    model.kind = kind;
    const Pose2 start{1.0, -2.0, 0.7};
    const OdometryControl u{1.2, 0.8, 0.2};
    const double dt = 1e-3;
    Eigen::Matrix<double, 3, 2> j;
    MoveRobot(model, start, u, dt, nullptr, &j);
    const Eigen::Matrix3d one_step = j * (kDensity / dt) * j.transpose();
    const Eigen::Matrix3d q = MotionNoise(model, start, u, dt, kDensity);
    EXPECT_LT((q - one_step).cwiseAbs().maxCoeff(), 2e-3 * one_step.cwiseAbs().maxCoeff());
  }
}

// Against the truth it models: a unicycle driven by the control plus white noise (fine steps
// of piecewise-constant noise of that density), 20000 seeded runs; the sample covariance of
// the end pose within its sampling error of Q, entry by entry.
TEST(MotionNoise, MatchesMonteCarloOfWhiteControlNoise) {
  const MotionModel model;
  const Pose2 start{0.5, 0.2, 0.3};
  const OdometryControl u{0.6, 0.9, 0.0};
  const double dt = 1.5, h = 5e-3;
  const Eigen::Matrix2d density = Eigen::Vector2d(0.01, 0.02).asDiagonal();
  const Eigen::Matrix3d q = MotionNoise(model, start, u, dt, density);
  const Pose2 mean = MoveRobot(model, start, u, dt);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int runs = 20000, steps = static_cast<int>(std::lround(dt / h));
  Eigen::Matrix3d sample = Eigen::Matrix3d::Zero();
  for (int r = 0; r < runs; ++r) {
    Pose2 p = start;
    for (int k = 0; k < steps; ++k) {
      p = UnicycleMotion(
          p, {u.v_mps + std::sqrt(density(0, 0) / h) * n01(rng), u.w_radps + std::sqrt(density(1, 1) / h) * n01(rng)},
          h);
    }
    const Eigen::Vector3d e(p.x - mean.x, p.y - mean.y, WrapAngle(p.theta - mean.theta));
    sample += e * e.transpose() / runs;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      // The sampling error of a covariance entry: sqrt((q_ii q_jj + q_ij^2) / runs); 4 of them.
      const double tolerance = 4.0 * std::sqrt((q(i, i) * q(j, j) + q(i, j) * q(i, j)) / runs);
      EXPECT_NEAR(sample(i, j), q(i, j), tolerance) << i << "," << j;
    }
  }
}

}  // namespace
}  // namespace mapmesh
