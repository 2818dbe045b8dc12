#include "agent/fusion_backend.h"

#include <gtest/gtest.h>

#include <random>

namespace mapmesh {
namespace {

constexpr double kSigma = 0.05;

// Ten well-spread landmarks, those with index in [first, last) seen by one robot with
// independent noise, in a frame placed at `frame` in the world.
LandmarkMap Seen(int first, int last, const Pose2& frame, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, kSigma);
  LandmarkMap m;
  for (int i = first; i < last; ++i) {
    const Eigen::Vector2d world(3.0 * i, (i % 3) * 4.0 + (i % 2) * 1.5);
    Landmark l;
    l.id = static_cast<std::uint32_t>(i - first);
    l.mean = frame.Inverse().Apply(world + Eigen::Vector2d(n(rng), n(rng)));
    l.cov = kSigma * kSigma * Eigen::Matrix2d::Identity();
    m.landmarks.push_back(l);
  }
  m.shape_sigma_m = kSigma;
  return m;
}

MapSource Source(RobotId robot, const LandmarkMap& map, const Pose2& to_own) {
  return MapSource{robot, 1, map, to_own, 1e-8 * Eigen::Matrix3d::Identity()};
}

// The global landmark fused from our landmark `own_id` and one of each source.
const Landmark& Fused(const GlobalMap& g, std::uint32_t own_id) {
  for (std::size_t i = 0; i < g.origins.size(); ++i) {
    if (g.origins[i].front().robot == 1 && g.origins[i].front().id == own_id) return g.map.landmarks[i];
  }
  ADD_FAILURE() << "no global landmark anchored at own landmark " << own_id;
  return g.map.landmarks.front();
}

class FusionBackendTest : public ::testing::Test {
 protected:
  std::mt19937_64 rng{4};
  const Pose2 frame2{5.0, -3.0, 0.7}, frame3{-2.0, 6.0, -1.1};
  const LandmarkMap own = Seen(0, 6, Pose2{}, rng);    // landmarks 0-5
  const LandmarkMap two = Seen(3, 9, frame2, rng);     // 3-8, three shared with ours
  const LandmarkMap three = Seen(7, 10, frame3, rng);  // 7-9: known to us only through robot 2's relay
};

TEST_F(FusionBackendTest, CovarianceIntersectionNeverCountsASharedLandmarkTwice) {
  GlobalMapOptions o;
  o.method = FusionMethod::kCiConstant;
  const auto ci = MakeFusionBackend(1, 1, o);
  const FusionBackend::Built b = ci->Build(own, {Source(2, two, frame2)}, {Source(2, two, frame2)});
  EXPECT_EQ(b.global.map.size(), 9u);  // the union: 0-8
  // Two equal covariances fused with equal weights: the covariance of either, not half of it.
  const Landmark& shared = Fused(b.global, 4);
  EXPECT_EQ(b.global.origins[&shared - b.global.map.landmarks.data()].size(), 2u);
  EXPECT_NEAR(shared.cov(0, 0), kSigma * kSigma, 1e-3 * kSigma * kSigma);
  EXPECT_EQ(b.published.map.size(), 9u);
}

// A submap of the world's landmarks [first, last) seen exactly from `frame` (keys from 0, as Seen's
// ids), its end pose 1 m ahead.
WireSubmap ExactSubmap(RobotId robot, std::uint32_t index, int first, int last, const Pose2& frame) {
  WireSubmap s;
  s.id = {robot, 1, index};
  s.closed_s = 1.0;
  s.x = Eigen::VectorXd(3 + 2 * (last - first));
  s.x.head<3>() << 1.0, 0.5, 0.1;
  for (int i = first; i < last; ++i) {
    const Eigen::Vector2d world(3.0 * i, (i % 3) * 4.0 + (i % 2) * 1.5);
    s.keys.push_back(static_cast<std::uint32_t>(i - first));
    s.x.segment<2>(3 + 2 * (i - first)) = frame.Inverse().Apply(world);
  }
  const auto n = s.x.size();
  Eigen::MatrixXd p = kSigma * kSigma * Eigen::MatrixXd::Identity(n, n);
  p.topLeftCorner<3, 3>() *= 0.01;
  EXPECT_TRUE(s.SetCovariance(p));
  return s;
}

// With submap chains (cekf_submaps), joining takes every landmark a chain holds from the joint
// estimate of the chains (here exact measurements: the truth, whatever the noisy maps say), and
// a landmark no chain holds (robot 2's last, mapped after its submap) from the CI build.
TEST_F(FusionBackendTest, JoiningOnSubmapChainsTakesTheChainsEstimates) {
  GlobalMapOptions o;
  o.method = FusionMethod::kJoining;
  SubmapBook book;
  const WireSubmap theirs = ExactSubmap(2, 0, 3, 8, frame2);  // landmarks 3-7 (their ids 0-4), not 8
  book.Add(theirs, EncodeSubmap(theirs));
  const WireSubmap ours = ExactSubmap(1, 0, 0, 6, Pose2{});
  SubmapInputs inputs{&book, &ours, nullptr};
  const FusionBackend::Built b = MakeFusionBackend(1, 1, o)->Build(own, {Source(2, two, frame2)},
                                                                   {Source(2, two, frame2)}, inputs);
  GlobalMapOptions ci;
  ci.method = FusionMethod::kCiConstant;
  const std::vector<MapSource> sources = {Source(2, two, frame2)};
  const GlobalMap by_ci = BuildGlobalMap(own, 1, sources, ci, 1);
  ASSERT_EQ(b.global.map.size(), 9u);
  EXPECT_TRUE(b.joining.solved);
  EXPECT_EQ(b.joining.chains_joined, 2);
  EXPECT_EQ(b.joining.submaps, 2);
  int exact = 0;
  for (std::size_t g = 0; g < b.global.map.size(); ++g) {
    const LandmarkOrigin& first = b.global.origins[g].front();
    const bool only_theirs_unjoined = first.robot == 2 && first.id == 5;  // landmark 8
    const int world_i = first.robot == 1 ? static_cast<int>(first.id) : static_cast<int>(first.id) + 3;
    const Eigen::Vector2d truth(3.0 * world_i, (world_i % 3) * 4.0 + (world_i % 2) * 1.5);
    if (only_theirs_unjoined) {
      EXPECT_EQ(b.global.map.landmarks[g].mean, by_ci.map.landmarks[g].mean);
      continue;
    }
    EXPECT_LT((b.global.map.landmarks[g].mean - truth).norm(), 1e-6) << "landmark " << world_i;
    ++exact;
  }
  EXPECT_EQ(exact, 8);
  // Without submaps the same back-end joins the maps (noisy: not the truth).
  const FusionBackend::Built maps = MakeFusionBackend(1, 1, o)->Build(own, {Source(2, two, frame2)},
                                                                      {Source(2, two, frame2)});
  EXPECT_FALSE(maps.joining.solved);
  EXPECT_GT((Fused(maps.global, 4).mean - Eigen::Vector2d(12.0, 4.0)).norm(), 1e-3);
}

TEST_F(FusionBackendTest, JoiningCountsEachRobotsInformationOnce) {
  GlobalMapOptions o;
  o.method = FusionMethod::kJoining;
  const auto joining = MakeFusionBackend(1, 1, o);
  const FusionBackend::Built b = joining->Build(own, {Source(2, two, frame2)}, {Source(2, two, frame2)});
  EXPECT_EQ(b.global.map.size(), 9u);
  // Two independent equal measurements of a landmark: about half the covariance of either.
  const Landmark& shared = Fused(b.global, 4);
  EXPECT_LT(shared.cov(0, 0), 0.75 * kSigma * kSigma);
  EXPECT_GT(shared.cov(0, 0), 0.3 * kSigma * kSigma);
  // And its estimate lies where the landmark is (within a few sigma).
  EXPECT_LT((shared.mean - Eigen::Vector2d(12.0, 4.0)).norm(), 4 * kSigma);
}

TEST_F(FusionBackendTest, ThePublishedMapHoldsTheOneHopMapsOnly) {
  GlobalMapOptions o;
  o.method = FusionMethod::kCiConstant;
  const auto ci = MakeFusionBackend(1, 1, o);
  // Robot 2's relay brings robot 3's landmarks 9 (7 and 8 robot 2 saw itself): the global map has
  // them, the published one (one hop: nothing relayed goes out again) does not.
  LandmarkMap relay = two;
  for (const Landmark& l : three.landmarks) {
    if (l.id == 2) relay.landmarks.push_back({100, -1, frame2.Inverse().Apply(frame3.Apply(l.mean)), l.cov});
  }
  const FusionBackend::Built b = ci->Build(own, {Source(2, relay, frame2)}, {Source(2, two, frame2)});
  EXPECT_EQ(b.global.map.size(), 10u);
  EXPECT_EQ(b.published.map.size(), 9u);
  // Joining uses the one-hop maps alone, in both.
  o.method = FusionMethod::kJoining;
  const FusionBackend::Built j = MakeFusionBackend(1, 1, o)->Build(own, {Source(2, relay, frame2)},
                                                                   {Source(2, two, frame2)});
  EXPECT_EQ(j.global.map.size(), 9u);
  EXPECT_EQ(j.published.map.size(), 9u);
}

}  // namespace
}  // namespace mapmesh
