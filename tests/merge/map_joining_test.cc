#include "common/merge/map_joining.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>

namespace mapmesh {
namespace {

// Two robots' maps of the same 30 landmarks (3 m apart, so that association is never in doubt),
// each landmark's error independent and as its
// covariance states, the peer's in a frame turned and moved by `truth`.
struct Scene {
  std::vector<Eigen::Vector2d> landmarks;
  LandmarkMap own, peer;
};

Scene MakeScene(const Pose2& truth, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-0.5, 0.5), us(0.05, 0.2);
  std::normal_distribution<double> g(0, 1);
  Scene s;
  const Pose2 inv = truth.Inverse();
  for (std::uint32_t i = 0; i < 30; ++i) {
    const Eigen::Vector2d p(3.0 * (i % 6) + u(rng), 3.0 * (i / 6) + u(rng));
    s.landmarks.push_back(p);
    for (int m = 0; m < 2; ++m) {
      const double sx = us(rng), sy = us(rng);
      Landmark l;
      l.id = i;
      l.signature = static_cast<std::int32_t>(i);
      l.cov = Eigen::Vector2d(sx * sx, sy * sy).asDiagonal();
      const Eigen::Vector2d noise(sx * g(rng), sy * g(rng));
      l.mean = (m == 0 ? p : inv.Apply(p)) + noise;
      (m == 0 ? s.own : s.peer).landmarks.push_back(l);
    }
  }
  return s;
}

TEST(MapJoining, JointLeastSquaresIsConsistentOnIndependentMaps) {
  std::mt19937_64 rng(21);
  const Pose2 truth{5, -3, 0.6};
  double nees = 0, sq_joined = 0, sq_own = 0;
  int n = 0;
  for (int run = 0; run < 100; ++run) {
    const Scene s = MakeScene(truth, rng);
    MapSource src;
    src.robot = 2;
    src.incarnation = 1;
    src.map = s.peer;
    src.to_own = {truth.x + 0.05, truth.y - 0.05, truth.theta + 0.01};  // an alignment, slightly off
    src.to_own_cov = Eigen::Vector3d(0.01, 0.01, 1e-4).asDiagonal();
    const std::vector<MapSource> sources{src};
    const GlobalMap ci = BuildGlobalMap(s.own, 1, sources, {}, 1);
    JoiningStats st;
    const GlobalMap joined = JoinMaps(s.own, 1, 1, sources, ci, &st);
    ASSERT_TRUE(st.solved);
    EXPECT_TRUE(st.converged);
    ASSERT_EQ(joined.map.size(), 30u);
    for (std::size_t k = 0; k < joined.map.size(); ++k) {
      const Landmark& l = joined.map.landmarks[k];
      ASSERT_GE(l.signature, 0) << "associated wrongly";
      const Eigen::Vector2d e = l.mean - s.landmarks[static_cast<std::size_t>(l.signature)];
      nees += e.dot(l.cov.ldlt().solve(e));
      sq_joined += e.squaredNorm();
      sq_own += (s.own.landmarks[l.signature].mean - s.landmarks[static_cast<std::size_t>(l.signature)]).squaredNorm();
      ++n;
    }
  }
  nees /= n;
  RecordProperty("nees", std::to_string(nees));
  // Independent errors, counted once: the joint estimate is consistent (2 dof per landmark) ...
  EXPECT_NEAR(nees, 2.0, 0.25);
  // ... and more accurate than the own map alone, though the peer's map also has to fix its frame.
  EXPECT_LT(std::sqrt(sq_joined / n), 0.9 * std::sqrt(sq_own / n));
}

TEST(MapJoining, WithoutSourcesTheOwnMapIsUnchanged) {
  std::mt19937_64 rng(22);
  const Scene s = MakeScene({1, 2, 0.3}, rng);
  const GlobalMap ci = BuildGlobalMap(s.own, 1, {}, {}, 1);
  const GlobalMap joined = JoinMaps(s.own, 1, 1, {}, ci);
  ASSERT_EQ(joined.map.size(), s.own.size());
  for (std::size_t k = 0; k < joined.map.size(); ++k) {
    EXPECT_LT((joined.map.landmarks[k].mean - ci.map.landmarks[k].mean).norm(), 1e-9);
    EXPECT_LT((joined.map.landmarks[k].cov - ci.map.landmarks[k].cov).norm(), 1e-9);
  }
}

}  // namespace
}  // namespace mapmesh
