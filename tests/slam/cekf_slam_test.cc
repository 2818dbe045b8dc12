#include "common/slam/cekf_slam.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "common/slam/ekf_slam.h"
#include "sim_feeder/simulator.h"

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

// Feeds the simulator's stream to several filters with known association.
void Feed(const Scenario& sc, const std::vector<LandmarkFilter*>& filters, int* inits = nullptr) {
  Simulator sim(sc, BuildWorld(sc));
  while (!sim.Done()) {
    const FeedBatch b = sim.Next();
    for (const Odometry& o : b.odom) {
      for (LandmarkFilter* f : filters) f->Predict({o.v, o.w, 0.0}, o.dt);
    }
    for (const Scan& s : b.scans) {
      std::vector<std::pair<LandmarkId, Eigen::Vector2d>> known, fresh;
      for (const Observation& o : s.obs) {
        const auto id = static_cast<LandmarkId>(o.signature);
        (filters[0]->Has(id) ? known : fresh).push_back({id, {o.range, o.bearing}});
      }
      for (LandmarkFilter* f : filters) {
        ASSERT_TRUE(f->Update(known));
        for (const auto& [id, z] : fresh) f->Add(id, z);
      }
      if (inits) *inits += static_cast<int>(fresh.size());
    }
  }
}

class CekfEqualsEkfTest : public ::testing::TestWithParam<int> {};

TEST_P(CekfEqualsEkfTest, FinalMeanAndCovarianceEqualTheFullEkf) {
  const Scenario sc = RandomWorld(GetParam(), 150);
  EkfSlam ekf(ThesisNoise());
  CekfSlam cekf(ThesisNoise(), {/*region_half_m=*/3.0, /*reach_m=*/9.0});
  int inits = 0;
  Feed(sc, {&ekf, &cekf}, &inits);
  // The run switched regions many times, and added landmarks inside compressed periods.
  EXPECT_GE(cekf.switches(), 5);
  EXPECT_GT(inits, 10);
  Eigen::VectorXd xe, xc;
  Eigen::MatrixXd pe, pc;
  std::vector<LandmarkId> ie, ic;
  ekf.FullState(&xe, &pe, &ie);
  cekf.FullState(&xc, &pc, &ic);
  ASSERT_EQ(ie, ic);
  ASSERT_EQ(xe.size(), xc.size());
  const double dx = (xe - xc).cwiseAbs().maxCoeff() / std::max(1.0, xe.cwiseAbs().maxCoeff());
  const double dp = (pe - pc).cwiseAbs().maxCoeff() / pe.cwiseAbs().maxCoeff();
  EXPECT_LT(dx, 1e-9);
  EXPECT_LT(dp, 1e-9);
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

INSTANTIATE_TEST_SUITE_P(Seeds, CekfEqualsEkfTest, ::testing::Range(1, 21));

TEST(EkfSlam, CovarianceStaysSymmetricPositiveSemiDefiniteOverALongRun) {
  for (int seed : {11, 12}) {
    const Scenario sc = RandomWorld(seed, 900);
    EkfSlam ekf(ThesisNoise());
    CekfSlam cekf(ThesisNoise(), {});
    Feed(sc, {&ekf, &cekf});
    for (const LandmarkFilter* f : {static_cast<const LandmarkFilter*>(&ekf), static_cast<const LandmarkFilter*>(&cekf)}) {
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
  EkfSlam ekf(ThesisNoise());
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

}  // namespace
}  // namespace mapmesh
