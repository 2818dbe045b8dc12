#include "common/slam/cekf_slam.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <random>

#include "common/slam/ekf_slam.h"
#include "common/slam/observation_model.h"
#include "sim_feeder/simulator.h"
#include "tests/testing/feed_filters.h"

namespace mapmesh {
namespace {

FilterNoise ThesisNoise() {
  FilterNoise n;
  n.control_cov = Eigen::Vector2d(0.03 * 0.03, 0.0524 * 0.0524).asDiagonal();
  n.obs_cov = Eigen::Vector2d(0.05 * 0.05, std::pow(DegToRad(1.0), 2)).asDiagonal();
  return n;
}

Scenario RandomWorld(int seed, double duration_s) {
  return ParseScenario("seed: " + std::to_string(seed) + "\nduration_s: " + std::to_string(duration_s) + R"(
world: {landmarks: {generator: {count: 160, area_m: [0, 0, 60, 60], min_spacing_m: 1.5}}}
robots:
  count: 1
  defaults: {preset: thesis, path: {type: random, count: 6}, sensor: {signatures: true}}
)",
                       "cekf.yaml");
}

// The compressed filter's full state (mean and covariance) equals the full EKF's to 1e-9 of
// the largest entry.
void ExpectSameFullState(const EkfSlam& ekf, const CekfSlam& cekf) {
  Eigen::VectorXd xe, xc;
  Eigen::MatrixXd pe, pc;
  std::vector<LandmarkId> ie, ic;
  ekf.FullState(&xe, &pe, &ie);
  cekf.FullState(&xc, &pc, &ic);
  ASSERT_EQ(ie, ic);
  ASSERT_EQ(xe.size(), xc.size());
  EXPECT_LT((xe - xc).cwiseAbs().maxCoeff() / std::max(1.0, xe.cwiseAbs().maxCoeff()), 1e-9);
  EXPECT_LT((pe - pc).cwiseAbs().maxCoeff() / pe.cwiseAbs().maxCoeff(), 1e-9);
}

// Seed, and whether the filters use first-estimates Jacobians.
class CekfEqualsEkfTest : public ::testing::TestWithParam<std::tuple<int, bool>> {};

TEST_P(CekfEqualsEkfTest, FinalMeanAndCovarianceEqualTheFullEkf) {
  const auto [seed, fej] = GetParam();
  const Scenario sc = RandomWorld(seed, 150);
  const EkfOptions eo{fej};
  EkfSlam ekf(ThesisNoise(), eo);
  CekfSlam cekf(ThesisNoise(), {/*region_half_m=*/3.0, /*reach_m=*/9.0}, eo);
  int inits = 0;
  testing::FeedFilters(sc, {&ekf, &cekf}, &inits);
  // The run switched regions many times, and added landmarks inside compressed periods.
  EXPECT_GE(cekf.switches(), 5);
  EXPECT_GT(inits, 10);
  ExpectSameFullState(ekf, cekf);
  Eigen::VectorXd xe;
  Eigen::MatrixXd pe;
  std::vector<LandmarkId> ids;
  ekf.FullState(&xe, &pe, &ids);
  // The map both publish agrees as well (the compressed one without a batch update).
  const LandmarkMap me = ekf.Map(), mc = cekf.Map();
  ASSERT_EQ(me.size(), mc.size());
  for (std::size_t i = 0; i < me.size(); ++i) {
    EXPECT_EQ(me.landmarks[i].id, mc.landmarks[i].id);
    EXPECT_LT((me.landmarks[i].mean - mc.landmarks[i].mean).norm(), 1e-9 * std::max(1.0, xe.cwiseAbs().maxCoeff()));
    EXPECT_LT((me.landmarks[i].cov - mc.landmarks[i].cov).cwiseAbs().maxCoeff(), 1e-9 * pe.cwiseAbs().maxCoeff());
  }
  // Cross-covariances of any two landmarks (active or passive, mid-period) agree too.
  int pairs = 0;
  for (std::size_t i = 0; i < me.size(); ++i) {
    for (std::size_t j = 0; j < me.size(); ++j) {
      const LandmarkId a = me.landmarks[i].id, b = me.landmarks[j].id;
      EXPECT_LT((ekf.CrossCov(a, b) - cekf.CrossCov(a, b)).cwiseAbs().maxCoeff(), 1e-9 * pe.cwiseAbs().maxCoeff());
      ++pairs;
    }
  }
  EXPECT_GT(pairs, 100);
  EXPECT_GT(cekf.active_landmarks(), 0u);
  EXPECT_LT(cekf.active_landmarks(), me.size());  // both kinds were compared
}

INSTANTIATE_TEST_SUITE_P(Seeds, CekfEqualsEkfTest, ::testing::Combine(::testing::Range(1, 21), ::testing::Bool()),
                         [](const ::testing::TestParamInfo<std::tuple<int, bool>>& info) {
                           return "seed" + std::to_string(std::get<0>(info.param)) +
                                  (std::get<1>(info.param) ? "_fej" : "_standard");
                         });

TEST(EkfSlam, CovarianceStaysSymmetricPositiveSemiDefiniteOverALongRun) {
  for (const auto& [seed, fej] :
       {std::pair{11, false}, std::pair{12, false}, std::pair{11, true}, std::pair{12, true}}) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed << (fej ? ", first-estimates Jacobians" : ""));
    const Scenario sc = RandomWorld(seed, 900);
    EkfSlam ekf(ThesisNoise(), {fej});
    CekfSlam cekf(ThesisNoise(), {/*region_half_m=*/5.0, /*reach_m=*/12.0}, {fej});
    testing::FeedFilters(sc, {&ekf, &cekf});
    for (const LandmarkFilter* f :
         {static_cast<const LandmarkFilter*>(&ekf), static_cast<const LandmarkFilter*>(&cekf)}) {
      Eigen::VectorXd x;
      Eigen::MatrixXd p;
      std::vector<LandmarkId> ids;
      f->FullState(&x, &p, &ids);
      EXPECT_GT(ids.size(), 50u);
      EXPECT_LT((p - p.transpose()).cwiseAbs().maxCoeff(), 1e-12 * p.cwiseAbs().maxCoeff());
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(p);
      EXPECT_GT(es.eigenvalues().minCoeff(), -1e-9 * es.eigenvalues().maxCoeff());
    }
  }
}

TEST(EkfSlam, PredictDoesNotTouchTheLandmarkBlock) {
  EkfSlam ekf(ThesisNoise(), EkfOptions{/*first_estimates_jacobians=*/false});
  ekf.Add(1, {5.0, 0.3});
  ekf.Add(2, {7.0, -0.4});
  ekf.Predict({0.3, 0.1, 0.0}, 0.1);
  Eigen::VectorXd x0;
  Eigen::MatrixXd p0;
  std::vector<LandmarkId> ids;
  ekf.FullState(&x0, &p0, &ids);
  for (int k = 0; k < 50; ++k) ekf.Predict({0.3, 0.1, 0.0}, 0.1);
  Eigen::VectorXd x1;
  Eigen::MatrixXd p1;
  ekf.FullState(&x1, &p1, &ids);
  EXPECT_EQ(p0.bottomRightCorner(4, 4), p1.bottomRightCorner(4, 4));
  EXPECT_EQ(x0.tail(4), x1.tail(4));
  EXPECT_NE(p0.topLeftCorner(3, 3), p1.topLeftCorner(3, 3));
}

// ---- First-estimates Jacobians (FEJ-EKF, Huang, Mourikis & Roumeliotis) ----

Eigen::Vector2d Turned(const Eigen::Vector2d& v) { return {-v.y(), v.x()}; }  // J v: 90 degrees
Eigen::Vector2d Position(const Pose2& p) { return {p.x, p.y}; }

const Eigen::Matrix2d kControlCov = Eigen::Vector2d(0.03 * 0.03, 0.05 * 0.05).asDiagonal();
// Odometry noise of kControlCov over 0.1 s (the unicycle).
FilterNoise ControlNoise() {
  FilterNoise n;
  n.control_cov = kControlCov;
  n.control_period_s = 0.1;
  return n;
}
const Eigen::Matrix2d kObsCov = Eigen::Vector2d(0.05 * 0.05, std::pow(DegToRad(1.0), 2)).asDiagonal();

// A state whose robot has moved and seen two landmarks, then moved on, and an update with
// observations that disagree with it, so that both the robot and the landmarks move.
struct MovedState {
  EkfState s;
  int a = 0, b = 0;
  Eigen::Vector2d first_a, first_b;
  Pose2 propagated;  // the robot before the update

  explicit MovedState(bool fej) : s(EkfOptions{fej}) {
    s.Predict(ControlNoise(), {0.3, 0.1, 0.0}, 1.0);
    a = s.Augment({5.0, 0.4}, kObsCov);
    b = s.Augment({6.0, -0.5}, kObsCov);
    first_a = s.landmark(a);
    first_b = s.landmark(b);
    for (int k = 0; k < 5; ++k) s.Predict(ControlNoise(), {0.3, 0.1, 0.0}, 1.0);
    propagated = s.robot();
    const Eigen::Vector2d za = s.Predicted(a, nullptr, nullptr) + Eigen::Vector2d(0.3, 0.05);
    const Eigen::Vector2d zb = s.Predicted(b, nullptr, nullptr) + Eigen::Vector2d(-0.2, 0.04);
    EXPECT_TRUE(s.Update({{a, za}, {b, zb}}, kObsCov));
  }
};

TEST(EkfSlamFirstEstimates, ObservationJacobiansAreAtTheFirstEstimateAndThePropagatedPose) {
  MovedState m(true);
  const EkfState& s = m.s;
  ASSERT_GT((s.landmark(m.a) - m.first_a).norm(), 0.01);
  ASSERT_GT((Position(s.robot()) - Position(m.propagated)).norm(), 0.01);
  EXPECT_EQ(s.first_estimate(m.a), m.first_a);  // an update does not move first estimates
  EXPECT_EQ(s.first_estimate(m.b), m.first_b);
  for (const auto& [slot, first] : {std::pair{m.a, m.first_a}, std::pair{m.b, m.first_b}}) {
    Matrix23 hr, hr_expected, hr_latest;
    Eigen::Matrix2d hl, hl_expected, hl_latest;
    s.Jacobians(slot, &hr, &hl);
    ObserveRangeBearing(m.propagated, first, &hr_expected, &hl_expected);
    EXPECT_LT((hr - hr_expected).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((hl - hl_expected).cwiseAbs().maxCoeff(), 1e-12);
    // Not the latest estimates, which Predicted (the innovations) uses.
    s.Predicted(slot, &hr_latest, &hl_latest);
    EXPECT_GT((hl - hl_latest).cwiseAbs().maxCoeff(), 1e-4);
  }
  // Without the option the update uses the latest estimates.
  MovedState standard(false);
  Matrix23 hr, hr_latest;
  Eigen::Matrix2d hl, hl_latest;
  standard.s.Jacobians(standard.a, &hr, &hl);
  standard.s.Predicted(standard.a, &hr_latest, &hl_latest);
  EXPECT_EQ(hr, hr_latest);
  EXPECT_EQ(hl, hl_latest);
}

TEST(EkfSlamFirstEstimates, PropagationJacobianCountsThePositionChangeFromThePropagatedPose) {
  for (bool fej : {false, true}) {
    MovedState m(fej);
    EkfState& s = m.s;
    const Pose2 updated = s.robot();
    const MotionModel model;
    Eigen::Matrix3d j_latest;
    MoveRobot(model, updated, {0.3, -0.2, 0.0}, 0.5, &j_latest);
    const Eigen::Matrix3d j = s.Predict(ControlNoise(), {0.3, -0.2, 0.0}, 0.5);
    const Pose2 next = s.robot();
    // The standard EKF: J (p' - p_updated); FEJ: J (p' - p_propagated), so that successive
    // steps chain: J (p3 - p2) + J (p2 - p1) = J (p3 - p1).
    const Eigen::Vector2d from = fej ? Position(m.propagated) : Position(updated);
    EXPECT_LT((j.block<2, 1>(0, 2) - Turned(Position(next) - from)).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_EQ(j.leftCols<2>(), j_latest.leftCols<2>());
    EXPECT_EQ(j(2, 2), 1.0);
    if (fej) {
      EXPECT_GT((j - j_latest).cwiseAbs().maxCoeff(), 1e-3);
    } else {
      EXPECT_LT((j - j_latest).cwiseAbs().maxCoeff(), 1e-12);
    }
    // The new propagated pose is the linearisation point of the next step.
    EXPECT_EQ(s.first_estimates().head<3>(), next.Vector());
  }
}

TEST(EkfSlamFirstEstimates, InitialisationJacobianIsAtTheNewFirstEstimateAndThePropagatedPose) {
  MovedState m(true);
  Matrix23 gr;
  const int c = m.s.Augment({4.0, 0.2}, kObsCov, &gr);
  EXPECT_EQ(m.s.first_estimate(c), m.s.landmark(c));
  Matrix23 expected;
  const Eigen::Vector2d d = Turned(m.s.landmark(c) - Position(m.propagated));
  expected << 1, 0, d.x(), 0, 1, d.y();
  EXPECT_LT((gr - expected).cwiseAbs().maxCoeff(), 1e-12);
}

// The point of FEJ: the linearised filter gains no information along the directions no
// sensor observes (a global translation or rotation of robot and map), so it does not become
// overconfident. With N the 3 unobservable directions at the linearisation points,
// N^T P^-1 N can only shrink (process noise), never grow; the standard EKF makes it grow.
TEST(EkfSlamFirstEstimates, UnobservableDirectionsGainNoInformation) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n01(0.0, 1.0);
  const std::vector<Eigen::Vector2d> world{{4, 1}, {6, -3}, {2, 5}, {-3, 4}, {-5, -2}, {1, -6}, {7, 4}, {-6, 3}};
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(3);
  const Eigen::MatrixXd p0 = Eigen::Vector3d(0.04, 0.04, 0.01).asDiagonal();  // a full-rank start
  auto unobservable = [](const EkfState& s, const Eigen::VectorXd& at) {
    Eigen::MatrixXd n = Eigen::MatrixXd::Zero(s.size(), 3);
    n.block<2, 2>(0, 0).setIdentity();
    n.block<2, 1>(0, 2) = Turned(at.head<2>());
    n(2, 2) = 1.0;
    for (int i = 0; i < s.landmarks(); ++i) {
      n.block<2, 2>(3 + 2 * i, 0).setIdentity();
      n.block<2, 1>(3 + 2 * i, 2) = Turned(at.segment<2>(3 + 2 * i));
    }
    return n;
  };
  auto information = [&](const EkfState& s, bool fej) {
    const Eigen::MatrixXd n = unobservable(s, fej ? Eigen::VectorXd(s.first_estimates()) : Eigen::VectorXd(s.x()));
    const Eigen::MatrixXd p = s.P();
    return Eigen::MatrixXd(n.transpose() * p.ldlt().solve(n));
  };
  double largest_gain[2] = {0.0, 0.0};
  for (bool fej : {false, true}) {
    EkfState s(x0, p0, EkfOptions{fej});
    Pose2 truth;
    std::vector<int> slot(world.size(), -1);
    for (int step = 1; step <= 300; ++step) {
      const UnicycleControl u{0.3, 0.25};
      truth = UnicycleMotion(truth, u, 0.1);
      Eigen::MatrixXd before = information(s, fej);
      s.Predict(ControlNoise(), {u.v_mps + 0.03 * n01(rng), u.w_radps + 0.05 * n01(rng), 0.0}, 0.1);
      Eigen::MatrixXd after = information(s, fej);
      largest_gain[fej] = std::max(largest_gain[fej], (after - before).eigenvalues().real().maxCoeff() / before.norm());
      if (step % 5 != 0) continue;
      std::vector<EkfState::Measurement> seen;
      std::vector<std::pair<int, Eigen::Vector2d>> fresh;
      for (std::size_t i = 0; i < world.size(); ++i) {
        Eigen::Vector2d z = ObserveRangeBearing(truth, world[i]);
        if (z(0) > 8.0) continue;
        z += Eigen::Vector2d(0.05 * n01(rng), DegToRad(1.0) * n01(rng));
        if (slot[i] >= 0) {
          seen.push_back({slot[i], z});
        } else {
          fresh.emplace_back(static_cast<int>(i), z);
        }
      }
      before = information(s, fej);
      ASSERT_TRUE(s.Update(seen, kObsCov));
      after = information(s, fej);
      largest_gain[fej] = std::max(largest_gain[fej], (after - before).eigenvalues().real().maxCoeff() / before.norm());
      for (const auto& [i, z] : fresh) {
        before = information(s, fej);
        slot[i] = s.Augment(z, kObsCov);
        after = information(s, fej);
        largest_gain[fej] = std::max(largest_gain[fej],
                                     (after - before).eigenvalues().real().maxCoeff() / before.norm());
      }
    }
    EXPECT_EQ(s.landmarks(), static_cast<int>(world.size()));
  }
  EXPECT_LT(largest_gain[true], 1e-7);
  EXPECT_GT(largest_gain[false], 1e-3);  // the standard EKF's spurious information
}

// The compressed filter keeps the first estimates (and the robot's propagated pose) across a
// batch update, even one forced right after an update, so it still equals the full EKF.
TEST(EkfSlamFirstEstimates, CompressedFilterSwitchingAfterAnUpdateEqualsTheFullEkf) {
  const Scenario sc = RandomWorld(4, 120);
  EkfSlam ekf(ThesisNoise(), {true});
  CekfSlam cekf(ThesisNoise(), {/*region_half_m=*/4.0, /*reach_m=*/9.0}, {true});
  Simulator sim(sc, BuildWorld(sc));
  int scans = 0;
  while (!sim.Done()) {
    const FeedBatch b = sim.Next();
    for (const Odometry& o : b.odom) {
      ekf.Predict({o.v, o.w, 0.0}, o.dt);
      cekf.Predict({o.v, o.w, 0.0}, o.dt);
    }
    for (const Scan& s : b.scans) {
      std::vector<std::pair<LandmarkId, Eigen::Vector2d>> known, fresh;
      for (const Observation& o : s.obs) {
        const auto id = static_cast<LandmarkId>(o.signature);
        (ekf.Has(id) ? known : fresh).push_back({id, {o.range, o.bearing}});
      }
      ASSERT_TRUE(ekf.Update(known));
      ASSERT_TRUE(cekf.Update(known));
      if (++scans % 7 == 0) cekf.Switch();  // the robot's estimate is not its propagated pose now
      for (const auto& [id, z] : fresh) {
        ekf.Add(id, z);
        cekf.Add(id, z);
      }
    }
  }
  EXPECT_GT(cekf.switches(), 20);
  ExpectSameFullState(ekf, cekf);
}

}  // namespace
}  // namespace mapmesh
