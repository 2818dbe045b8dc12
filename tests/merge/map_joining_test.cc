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

// Three maps of the same landmarks; in the second peer's, one landmark sits 1 m from where the
// others put it (a biased stretch of its map). Plain least squares moves the joined landmark
// by a third of that; the Huber kernel leaves it with the two maps that agree, and the other
// landmarks are unaffected either way.
TEST(MapJoining, HuberKernelKeepsOneBiasedLandmarkCopyFromDraggingTheJoinedLandmark) {
  std::mt19937_64 rng(23);
  const Pose2 t2{5, -3, 0.6}, t3{-4, 2, -1.1};
  const Scene a = MakeScene(t2, rng);
  Scene b = MakeScene(t3, rng);
  const std::uint32_t biased = 14;
  std::vector<MapSource> sources(2);
  sources[0].robot = 2;
  sources[0].map = a.peer;
  sources[0].to_own = t2;
  sources[1].robot = 3;
  sources[1].map = b.peer;
  sources[1].to_own = t3;
  for (MapSource& src : sources) {
    src.incarnation = 1;
    src.to_own_cov = Eigen::Vector3d(0.01, 0.01, 1e-4).asDiagonal();
  }
  // b's own map is not used; its peer map gives the third robot's map of a's landmarks (with b's
  // noise, moved onto a's truth positions).
  for (std::uint32_t i = 0; i < 30; ++i) {
    const Eigen::Vector2d noise = b.peer.landmarks[i].mean - t3.Inverse().Apply(b.landmarks[i]);
    sources[1].map.landmarks[i].mean = t3.Inverse().Apply(a.landmarks[i]) + noise;
  }
  // The association is the true one (built before the bias, which the CI gates would refuse).
  const GlobalMap ci = BuildGlobalMap(a.own, 1, sources, {}, 1);
  ASSERT_EQ(ci.map.size(), 30u);
  sources[1].map.landmarks[biased].mean += Eigen::Vector2d(0.0, 1.0);
  auto error_of = [&](const GlobalMap& m, std::int32_t signature) {
    for (const Landmark& l : m.map.landmarks)
      if (l.signature == signature) return (l.mean - a.landmarks[static_cast<std::size_t>(signature)]).norm();
    return 1e9;
  };
  JoiningOptions plain;
  plain.huber = 0.0;
  JoiningStats st_plain, st_huber;
  const GlobalMap lsq = JoinMaps(a.own, 1, 1, sources, ci, &st_plain, plain);
  const GlobalMap robust = JoinMaps(a.own, 1, 1, sources, ci, &st_huber);
  ASSERT_TRUE(st_plain.solved);
  ASSERT_TRUE(st_huber.solved);
  EXPECT_TRUE(st_huber.converged);
  EXPECT_EQ(st_plain.downweighted, 0);
  EXPECT_GE(st_huber.downweighted, 1);
  const auto sig = static_cast<std::int32_t>(biased);
  EXPECT_GT(error_of(lsq, sig), 0.2);
  EXPECT_LT(error_of(robust, sig), 0.6 * error_of(lsq, sig));
  double worst_other = 0;
  for (std::int32_t i = 0; i < 30; ++i)
    if (i != sig) worst_other = std::max(worst_other, error_of(robust, i));
  EXPECT_LT(worst_other, 0.6);
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
