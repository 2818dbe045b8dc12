#include "common/slam/observation_model.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/testing/numeric_jacobian.h"

namespace mapmesh {
namespace {

TEST(ObserveRangeBearing, ByHand) {
  // Robot at (1, 1) facing north; landmark at (4, 5): r = 5, b = atan2(4, 3) - pi/2.
  const Eigen::Vector2d z = ObserveRangeBearing({1, 1, M_PI / 2}, {4, 5});
  EXPECT_NEAR(z(0), 5.0, 1e-12);
  EXPECT_NEAR(z(1), std::atan2(4.0, 3.0) - M_PI / 2, 1e-12);
}

TEST(InverseRangeBearing, InvertsTheObservation) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-20, 20), ua(-M_PI, M_PI);
  for (int i = 0; i < 100; ++i) {
    const Pose2 robot{u(rng), u(rng), ua(rng)};
    const Eigen::Vector2d m(u(rng), u(rng));
    const Eigen::Vector2d back = InverseRangeBearing(robot, ObserveRangeBearing(robot, m));
    EXPECT_LT((back - m).norm(), 1e-9);
  }
}

class ObservationJacobianTest : public ::testing::TestWithParam<int> {};

TEST_P(ObservationJacobianTest, MatchNumericalDifferentiation) {
  std::mt19937_64 rng(GetParam());
  std::uniform_real_distribution<double> u(-20, 20), ua(-M_PI, M_PI), ur(0.5, 15), ub(-M_PI / 2, M_PI / 2);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector3d x(u(rng), u(rng), ua(rng));
    const Eigen::Vector2d m(x(0) + u(rng), x(1) + u(rng));
    Matrix23 hr;
    Eigen::Matrix2d hm;
    ObserveRangeBearing({x(0), x(1), x(2)}, m, &hr, &hm);
    auto fr = [&](const Eigen::VectorXd& s) { return Eigen::VectorXd(ObserveRangeBearing({s(0), s(1), s(2)}, m)); };
    auto fm = [&](const Eigen::VectorXd& s) {
      return Eigen::VectorXd(ObserveRangeBearing({x(0), x(1), x(2)}, Eigen::Vector2d(s)));
    };
    EXPECT_LT((hr - testing::NumericJacobian(fr, x, 1e-6, {1})).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LT((hm - testing::NumericJacobian(fm, m, 1e-6, {1})).cwiseAbs().maxCoeff(), 1e-7);

    const Eigen::Vector2d z(ur(rng), ub(rng));
    Matrix23 gr;
    Eigen::Matrix2d gz;
    InverseRangeBearing({x(0), x(1), x(2)}, z, &gr, &gz);
    auto gfr = [&](const Eigen::VectorXd& s) { return Eigen::VectorXd(InverseRangeBearing({s(0), s(1), s(2)}, z)); };
    auto gfz = [&](const Eigen::VectorXd& s) {
      return Eigen::VectorXd(InverseRangeBearing({x(0), x(1), x(2)}, Eigen::Vector2d(s)));
    };
    EXPECT_LT((gr - testing::NumericJacobian(gfr, x)).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LT((gz - testing::NumericJacobian(gfz, z)).cwiseAbs().maxCoeff(), 1e-7);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, ObservationJacobianTest, ::testing::Range(1, 6));

// The structure the first-estimates Jacobians (EkfState) rely on: with d = m - p and J the
// 90 degree rotation, H_robot = -H_landmark [I, J d] and G_robot = [I, J d], so a Jacobian
// evaluated at other points (a landmark's first estimate) keeps the global translation and
// rotation unobservable.
TEST(RangeBearingJacobians, RobotPartIsTheLandmarkPartTimesTheRigidMotion) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-10, 10), ua(-M_PI, M_PI);
  for (int trial = 0; trial < 20; ++trial) {
    const Pose2 robot{u(rng), u(rng), ua(rng)};
    const Eigen::Vector2d m(u(rng), u(rng));
    const Eigen::Vector2d d = m - Eigen::Vector2d(robot.x, robot.y);
    Matrix23 rigid;
    rigid << 1, 0, -d.y(), 0, 1, d.x();
    Matrix23 hr, gr;
    Eigen::Matrix2d hl;
    const Eigen::Vector2d z = ObserveRangeBearing(robot, m, &hr, &hl);
    EXPECT_LT((hr + hl * rigid).cwiseAbs().maxCoeff(), 1e-12);
    const Eigen::Vector2d back = InverseRangeBearing(robot, z, &gr);
    EXPECT_LT((back - m).norm(), 1e-9);
    EXPECT_LT((gr - rigid).cwiseAbs().maxCoeff(), 1e-9);
  }
}

}  // namespace
}  // namespace mapmesh
