#include "common/merge/global_map.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>

#include "common/metrics/landmark_metrics.h"

namespace mapmesh {
namespace {

// Landmark i of a world at a known place; the map holds it with noise drawn from cov.
LandmarkMap NoisyMap(const std::vector<Eigen::Vector2d>& world, const std::vector<int>& which, const Pose2& frame,
                     double sigma, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, sigma);
  LandmarkMap m;
  const Pose2 to_frame = frame.Inverse();
  for (int i : which) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(100 + i);
    l.signature = i;
    l.mean = to_frame.Apply(world[i] + Eigen::Vector2d(n(rng), n(rng)));
    l.cov = sigma * sigma * Eigen::Matrix2d::Identity();
    m.landmarks.push_back(l);
  }
  return m;
}

std::vector<Eigen::Vector2d> GridWorld(int n, double spacing) {
  std::vector<Eigen::Vector2d> w;
  for (int i = 0; i < n; ++i) w.emplace_back(spacing * (i % 10), spacing * (i / 10));
  return w;
}

std::vector<int> Range(int lo, int hi) {
  std::vector<int> v;
  for (int i = lo; i < hi; ++i) v.push_back(i);
  return v;
}

TEST(GlobalMap, TransformLandmarkCovarianceMatchesNumericalJacobian) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  for (int trial = 0; trial < 50; ++trial) {
    const Pose2 t{u(rng), u(rng), u(rng) / 3.0};
    Landmark l;
    l.mean = {u(rng), u(rng)};
    l.cov << 0.2, 0.05, 0.05, 0.1;
    Eigen::Matrix3d p = Eigen::Matrix3d::Zero();
    p.diagonal() << 0.3, 0.2, 0.01;
    p(0, 2) = p(2, 0) = 0.02;
    // Numerical d T(m) / d (x, y, theta).
    Eigen::Matrix<double, 2, 3> j;
    const double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d d = Eigen::Vector3d::Zero();
      d(k) = h;
      const Pose2 tp{t.x + d(0), t.y + d(1), t.theta + d(2)}, tm{t.x - d(0), t.y - d(1), t.theta - d(2)};
      j.col(k) = (tp.Apply(l.mean) - tm.Apply(l.mean)) / (2 * h);
    }
    const Eigen::Matrix2d expected = t.Rotation() * l.cov * t.Rotation().transpose() + j * p * j.transpose();
    const Landmark out = TransformLandmark(l, t, p);
    EXPECT_LT((out.cov - expected).norm(), 1e-6 * expected.norm());
    EXPECT_LT((out.mean - t.Apply(l.mean)).norm(), 1e-12);
  }
}

TEST(GlobalMap, TransformedLandmarksAreConsistentUnderTransformError) {
  // Monte Carlo: the landmark's and the transform's errors drawn from their covariances.
  std::mt19937_64 rng(2);
  std::normal_distribution<double> n(0.0, 1.0);
  const Pose2 truth{5.0, -3.0, 0.7};
  const Eigen::Vector3d sd(0.2, 0.1, 0.02);
  const Eigen::Vector2d m_true(8.0, 4.0);
  double nees = 0.0;
  const int runs = 20000;
  for (int k = 0; k < runs; ++k) {
    const Pose2 est{truth.x + sd(0) * n(rng), truth.y + sd(1) * n(rng), truth.theta + sd(2) * n(rng)};
    Landmark l;
    l.mean = m_true + 0.1 * Eigen::Vector2d(n(rng), n(rng));
    l.cov = 0.01 * Eigen::Matrix2d::Identity();
    const Landmark out = TransformLandmark(l, est, sd.array().square().matrix().asDiagonal());
    nees += Nees(out.mean, out.cov, truth.Apply(m_true));
  }
  EXPECT_NEAR(nees / runs, 2.0, 0.1);
}

TEST(GlobalMap, LocalOnlyIsAClone) {
  std::mt19937_64 rng(3);
  const auto world = GridWorld(30, 3.0);
  const LandmarkMap local = NoisyMap(world, Range(0, 30), {}, 0.1, rng);
  const GlobalMap g = BuildGlobalMap(local, 7, {}, {});
  ASSERT_EQ(g.map.size(), local.size());
  for (std::size_t i = 0; i < local.size(); ++i) {
    EXPECT_EQ(g.map.landmarks[i].mean, local.landmarks[i].mean);
    EXPECT_EQ(g.map.landmarks[i].cov, local.landmarks[i].cov);
    ASSERT_EQ(g.origins[i].size(), 1u);
    EXPECT_EQ(g.origins[i][0].robot, 7u);
    EXPECT_EQ(g.origins[i][0].id, local.landmarks[i].id);
  }
  EXPECT_EQ(g.stats.local, 30);
}

TEST(GlobalMap, OverlappingPeerIsAssociatedByGateAndTheRestAppended) {
  // The peer's frame is rotated and shifted; it shares landmarks 20-39 with the local map.
  std::mt19937_64 rng(4);
  const auto world = GridWorld(60, 3.0);
  const Pose2 peer_frame{12.0, -4.0, 1.1};
  int associated = 0, wrong = 0, fused_pairs = 0;
  const int trials = 50;
  for (int trial = 0; trial < trials; ++trial) {
    const LandmarkMap local = NoisyMap(world, Range(0, 40), {}, 0.1, rng);
    const LandmarkMap peer = NoisyMap(world, Range(20, 60), peer_frame, 0.1, rng);
    Eigen::Matrix3d tc = Eigen::Matrix3d::Zero();
    tc.diagonal() << 0.01, 0.01, 1e-5;
    const std::vector<MapSource> src{{2, 0, peer, peer_frame, tc}};
    const GlobalMap g = BuildGlobalMap(local, 1, src, {});
    EXPECT_EQ(g.stats.associated + g.stats.appended, 40);
    EXPECT_EQ(g.map.size(), 40u + g.stats.appended);
    associated += g.stats.associated;
    // Association against the truth (signatures): every fused pair is the same landmark.
    for (std::size_t i = 0; i < g.map.size(); ++i) {
      wrong += g.map.landmarks[i].signature < 0;  // inputs with different signatures
      fused_pairs += g.origins[i].size() == 2;
    }
  }
  EXPECT_EQ(wrong, 0);
  EXPECT_EQ(fused_pairs, associated);
  // The 99.9 % gate misses about one true pair in a thousand.
  EXPECT_GE(associated, static_cast<int>(0.99 * 20 * trials));
}

TEST(GlobalMap, AKnownIdentitySurvivesPeersWithoutOneAndConflictingOnesAreDropped) {
  LandmarkMap local;
  for (int i = 0; i < 3; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(i);
    l.signature = 10 + i;
    l.mean = {5.0 * i, 0.0};
    l.cov = Eigen::Matrix2d::Identity() * 0.01;
    local.landmarks.push_back(l);
  }
  LandmarkMap peer = local;
  peer.landmarks[0].signature = -1;  // a peer's map off the wire: identity unknown
  peer.landmarks[1].signature = 99;  // a different known identity
  peer.landmarks[2].signature = 12;  // the same one
  const std::vector<MapSource> src{{2, 1, peer, Pose2{}, Eigen::Matrix3d::Identity() * 1e-6}};
  const GlobalMap g = BuildGlobalMap(local, 1, src, {});
  ASSERT_EQ(g.map.size(), 3u);
  EXPECT_EQ(g.map.landmarks[0].signature, 10);
  EXPECT_EQ(g.map.landmarks[1].signature, -1);
  EXPECT_EQ(g.map.landmarks[2].signature, 12);
}

// Local landmarks at x = 0, 1, 10 (ids 0, 1, 10) and one peer's at 0.6, 1.6, 10.6 (ids 6, 16,
// 106), aligned by the identity with a covariance of 0.25 m^2 in x: the alignment is 0.6 m off,
// and its covariance says so.
struct NearestNeighbourTrap {
  LandmarkMap local;
  std::vector<MapSource> src;
  NearestNeighbourTrap() {
    LandmarkMap peer;
    const Eigen::Matrix2d c = 0.005 * Eigen::Matrix2d::Identity();
    for (double x : {0.0, 1.0, 10.0}) local.landmarks.push_back({static_cast<std::uint32_t>(x), -1, {x, 0.0}, c});
    for (double x : {0.6, 1.6, 10.6}) peer.landmarks.push_back({static_cast<std::uint32_t>(x * 10), -1, {x, 0.0}, c});
    Eigen::Matrix3d tc = Eigen::Matrix3d::Zero();
    tc.diagonal() << 0.25, 1e-4, 1e-8;
    src = {{2, 0, peer, Pose2{}, tc}};
  }
};

TEST(GlobalMap, JointCompatibilityResolvesWhatNearestNeighbourGetsWrong) {
  // The alignment is 0.6 m off in x, and its covariance says so (sigma 0.5 m in x): the
  // peer's landmark at 0.6 is individually nearer to the local one at 1.0 than to its true
  // partner at 0.0. Only the assignment that shifts all three together is jointly compatible.
  const NearestNeighbourTrap trap;
  const LandmarkMap& local = trap.local;
  const std::vector<MapSource>& src = trap.src;
  const GlobalMap g = BuildGlobalMap(local, 1, src, {});
  EXPECT_EQ(g.stats.ambiguous_groups, 1);
  EXPECT_EQ(g.stats.associated, 3);
  ASSERT_EQ(g.map.size(), 3u);
  for (std::size_t i = 0; i < 3; ++i) {
    ASSERT_EQ(g.origins[i].size(), 2u);
    EXPECT_EQ(g.origins[i][1].id, static_cast<std::uint32_t>(std::lround(10 * (local.landmarks[i].mean.x() + 0.6))));
  }
  // Greedy, closest first (JCBB disabled), pairs 0.6 with 1.0: a wrong association.
  GlobalMapOptions greedy;
  greedy.max_jcbb_landmarks = 0;
  const GlobalMap gg = BuildGlobalMap(local, 1, src, greedy);
  EXPECT_EQ(gg.stats.greedy_groups, 1);
  int correct = 0;
  for (std::size_t i = 0; i < gg.map.size(); ++i) {
    if (gg.origins[i].size() != 2) continue;
    const Landmark* l = local.Find(gg.origins[i][0].id);
    ASSERT_NE(l, nullptr);
    correct += gg.origins[i][1].id == static_cast<std::uint32_t>(std::lround(10 * (l->mean.x() + 0.6)));
  }
  EXPECT_LT(correct, 3);
}

// The pairing of each landmark of the global map, by the origins of its inputs.
std::vector<std::vector<std::array<std::uint32_t, 3>>> Pairings(const GlobalMap& g) {
  std::vector<std::vector<std::array<std::uint32_t, 3>>> out;
  for (const auto& inputs : g.origins) {
    out.emplace_back();
    for (const LandmarkOrigin& o : inputs) out.back().push_back({o.robot, o.incarnation, o.id});
  }
  return out;
}

TEST(GlobalMap, AMemoKeepsUnchangedGroupsAndBuildsWhatAFreshBuildDoes) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    std::mt19937_64 rng(seed);
    // Trees at random at least 0.5 m apart, alignments uncertain by 0.3 m: some ambiguous groups.
    std::vector<Eigen::Vector2d> world;
    std::uniform_real_distribution<double> u(0.0, 15.0);
    while (world.size() < 80) {
      const Eigen::Vector2d p(u(rng), u(rng));
      if (std::all_of(world.begin(), world.end(), [&](const auto& q) { return (q - p).norm() > 0.5; }))
        world.push_back(p);
    }
    const LandmarkMap local = NoisyMap(world, Range(0, 50), Pose2{}, 0.03, rng);
    Eigen::Matrix3d tc = Eigen::Matrix3d::Zero();
    tc.diagonal() << 0.09, 0.09, 1e-4;
    std::vector<MapSource> sources;
    for (RobotId r = 2; r <= 4; ++r) {
      const Pose2 frame{1.0 * r, -0.5 * r, 0.1 * r};
      sources.push_back({r, 0, NoisyMap(world, Range(10 * r - 10, 10 * r + 40), frame, 0.03, rng), frame, tc});
    }
    AssociationMemo memo;
    const GlobalMap fresh = BuildGlobalMap(local, 1, sources, {});
    const GlobalMap first = BuildGlobalMap(local, 1, sources, {}, 0, &memo);
    const AssociationMemo::Stats searched = memo.stats();
    ASSERT_GT(searched.searched, 0) << "seed " << seed;
    EXPECT_EQ(searched.reused, 0);
    EXPECT_EQ(Pairings(first), Pairings(fresh));
    // The same input again: every group keeps its pairing, and the map is the same.
    const GlobalMap again = BuildGlobalMap(local, 1, sources, {}, 0, &memo);
    EXPECT_EQ(memo.stats().reused, searched.searched);
    EXPECT_EQ(memo.stats().searched, 0);
    EXPECT_EQ(Pairings(again), Pairings(fresh));
    ASSERT_EQ(again.map.size(), fresh.map.size());
    for (std::size_t i = 0; i < fresh.map.size(); ++i) {
      EXPECT_EQ(again.map.landmarks[i].mean, fresh.map.landmarks[i].mean);
      EXPECT_EQ(again.map.landmarks[i].cov, fresh.map.landmarks[i].cov);
    }
    // Every estimate moved a little, as from one map period to the next: the groups are the
    // same, their pairings stand, and the map is what a fresh build of the new input gives.
    LandmarkMap moved_local = local;
    std::normal_distribution<double> n(0.0, 0.002);
    for (Landmark& l : moved_local.landmarks) l.mean += Eigen::Vector2d(n(rng), n(rng));
    for (MapSource& s : sources) {
      for (Landmark& l : s.map.landmarks) l.mean += Eigen::Vector2d(n(rng), n(rng));
    }
    const GlobalMap moved = BuildGlobalMap(moved_local, 1, sources, {}, 0, &memo);
    EXPECT_GT(memo.stats().reused, 0);
    EXPECT_EQ(Pairings(moved), Pairings(BuildGlobalMap(moved_local, 1, sources, {})));
  }
}

TEST(GlobalMap, AMemoSearchesAgainWhenTheKeptPairingIsNoLongerJointlyCompatible) {
  // The group of JointCompatibilityResolvesWhatNearestNeighbourGetsWrong: peer landmarks 6
  // and 16 both have local landmarks 0 and 1 as candidates.
  NearestNeighbourTrap trap;
  const LandmarkMap& local = trap.local;
  std::vector<MapSource>& src = trap.src;
  AssociationMemo memo;
  const GlobalMap first = BuildGlobalMap(local, 1, src, {}, 0, &memo);
  EXPECT_EQ(memo.stats().searched, 1);
  // The peer's landmarks 6 and 16 trade places: same members, same candidates, but pairing 6
  // with 0 and 16 with 1 now puts them 2 m apart relative to each other.
  std::swap(src[0].map.landmarks[0].mean, src[0].map.landmarks[1].mean);
  const GlobalMap second = BuildGlobalMap(local, 1, src, {}, 0, &memo);
  EXPECT_EQ(memo.stats().reused, 0);
  EXPECT_EQ(memo.stats().searched, 1);
  const GlobalMap fresh = BuildGlobalMap(local, 1, src, {});
  EXPECT_EQ(Pairings(second), Pairings(fresh));
  ASSERT_EQ(second.origins[0].size(), 2u);
  EXPECT_EQ(second.origins[0][1].id, 16u);  // local 0 now pairs with peer 16 (at 0.6)
  EXPECT_NE(Pairings(second), Pairings(first));
}

TEST(GlobalMap, EstimatorDecidesHowSharedLandmarksShrink) {
  std::mt19937_64 rng(5);
  const auto world = GridWorld(20, 3.0);
  const LandmarkMap local = NoisyMap(world, Range(0, 20), {}, 0.1, rng);
  const LandmarkMap peer = NoisyMap(world, Range(0, 20), {}, 0.1, rng);
  const std::vector<MapSource> src{{2, 0, peer, Pose2{}, Eigen::Matrix3d::Zero()}};
  GlobalMapOptions o;
  o.method = FusionMethod::kCiConstant;
  const GlobalMap ci = BuildGlobalMap(local, 1, src, o);
  o.method = FusionMethod::kInformation;
  const GlobalMap info = BuildGlobalMap(local, 1, src, o);
  ASSERT_EQ(ci.map.size(), 20u);
  ASSERT_EQ(info.map.size(), 20u);
  for (std::size_t i = 0; i < 20; ++i) {
    EXPECT_NEAR(ci.map.landmarks[i].cov(0, 0), 0.01, 1e-12);     // equal inputs: CI keeps the covariance
    EXPECT_NEAR(info.map.landmarks[i].cov(0, 0), 0.005, 1e-12);  // information fusion halves it
    EXPECT_LT((ci.map.landmarks[i].mean - info.map.landmarks[i].mean).norm(), 1e-12);
  }
}

TEST(GlobalMap, InvalidInputIsCountedAndNeverFused) {
  std::mt19937_64 rng(6);
  const auto world = GridWorld(10, 3.0);
  LandmarkMap local = NoisyMap(world, Range(0, 10), {}, 0.1, rng);
  LandmarkMap peer = NoisyMap(world, Range(0, 10), {}, 0.1, rng);
  local.landmarks[0].mean.x() = std::numeric_limits<double>::quiet_NaN();
  local.landmarks[1].cov << 1.0, 2.0, 2.0, 1.0;  // not PSD
  peer.landmarks[2].cov << 1.0, 1.0, 1.0, 1.0;   // singular
  peer.landmarks[3].cov(0, 0) = std::numeric_limits<double>::infinity();
  peer.landmarks[4].mean.y() = std::numeric_limits<double>::infinity();
  std::vector<MapSource> src{{2, 0, peer, Pose2{}, Eigen::Matrix3d::Zero()}};
  const GlobalMap g = BuildGlobalMap(local, 1, src, {});
  EXPECT_EQ(g.stats.rejected_landmarks, 5);
  EXPECT_EQ(g.stats.non_finite_mean, 2);
  EXPECT_EQ(g.stats.invalid_covariance, 2);
  EXPECT_EQ(g.stats.singular_covariance, 1);
  for (const Landmark& l : g.map.landmarks) {
    EXPECT_TRUE(l.mean.allFinite());
    EXPECT_TRUE(IsValidCovariance(l.cov));
  }
  // Landmarks 0 and 1 come only from the peer, 2-4 only from the local map.
  EXPECT_EQ(g.map.size(), 10u);
  // A source whose transform covariance is invalid is rejected whole.
  src[0].to_own_cov(0, 0) = -1.0;
  const GlobalMap bad = BuildGlobalMap(local, 1, src, {});
  EXPECT_EQ(bad.stats.rejected_sources, 1);
  EXPECT_EQ(bad.map.size(), 8u);
  src[0].to_own.theta = std::numeric_limits<double>::quiet_NaN();
  src[0].to_own_cov.setZero();
  EXPECT_EQ(BuildGlobalMap(local, 1, src, {}).stats.rejected_sources, 1);
  // Empty maps are fine.
  EXPECT_TRUE(BuildGlobalMap({}, 1, {}, {}).map.empty());
  const std::vector<MapSource> empty_src{{2, 0, {}, Pose2{}, Eigen::Matrix3d::Zero()}};
  EXPECT_EQ(BuildGlobalMap({}, 1, empty_src, {}).stats.sources, 1);
}

// Relay: each round, every robot rebuilds its global map from its local map and its peer's
// latest global map (which already holds its own information). Mean NEES per round.
std::vector<double> RelayNees(FusionMethod method, int rounds) {
  std::vector<double> nees(rounds, 0.0);
  const auto world = GridWorld(100, 3.0);
  const int seeds = 20;
  for (int seed = 0; seed < seeds; ++seed) {
    std::mt19937_64 rng(100 + seed);
    const LandmarkMap la = NoisyMap(world, Range(0, 100), {}, 0.1, rng);
    const LandmarkMap lb = NoisyMap(world, Range(0, 100), {}, 0.1, rng);
    GlobalMapOptions o;
    o.method = method;
    GlobalMap ga = BuildGlobalMap(la, 1, {}, o), gb = BuildGlobalMap(lb, 2, {}, o);
    for (int r = 0; r < rounds; ++r) {
      const std::vector<MapSource> to_a{{2, 0, gb.map, Pose2{}, Eigen::Matrix3d::Zero()}};
      const std::vector<MapSource> to_b{{1, 0, ga.map, Pose2{}, Eigen::Matrix3d::Zero()}};
      GlobalMap na = BuildGlobalMap(la, 1, to_a, o), nb = BuildGlobalMap(lb, 2, to_b, o);
      ga = std::move(na);
      gb = std::move(nb);
      nees[r] += EvaluateMap(ga.map, world, {}).nees_mean / seeds;
    }
  }
  return nees;
}

TEST(GlobalMap, RelayMakesInformationFusionOverconfidentWhileCiStaysConsistent) {
  const int rounds = 6;
  const std::vector<double> info = RelayNees(FusionMethod::kInformation, rounds);
  const std::vector<double> ci = RelayNees(FusionMethod::kCiConstant, rounds);
  const std::vector<double> ci_det = RelayNees(FusionMethod::kCiDeterminant, rounds);
  for (int r = 0; r < rounds; ++r) {
    std::printf("relay round %d: mean NEES information %.2f, CI %.2f, CI det %.2f\n", r + 1, info[r], ci[r], ci_det[r]);
  }
  // Round 1 fuses two independent maps: every estimator is consistent.
  EXPECT_NEAR(info[0], 2.0, 0.3);
  // Information fusion counts its own map again each round: NEES grows round on round.
  for (int r = 1; r < rounds; ++r) EXPECT_GT(info[r], info[r - 1] + 0.5) << "round " << r + 1;
  EXPECT_GT(info[rounds - 1], 5.0);
  // CI never claims more than it knows.
  for (int r = 0; r < rounds; ++r) {
    EXPECT_LT(ci[r], 2.5) << "round " << r + 1;
    EXPECT_LT(ci_det[r], 2.5) << "round " << r + 1;
  }
}

}  // namespace
}  // namespace mapmesh
