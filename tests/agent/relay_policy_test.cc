#include "agent/relay_policy.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "tests/testing/exchange_world.h"

namespace mapmesh {
namespace {

// The world of the exchange's tests, its maps with 3 cm noise.
constexpr double kSigma = 0.03;
struct World : test::World {
  explicit World(std::uint64_t seed) : test::World(160, seed) {}
  LandmarkMap Map(double x0, double x1, const Pose2& frame, std::mt19937_64& rng) const {
    return test::World::Map(x0, x1, frame, kSigma, rng);
  }
};

// Our frame is the world's; peers' frames are elsewhere. `to_own` of a frame is its pose.
const Pose2 kFrameP{20.0, 5.0, 1.2}, kFrameQ{35.0, 30.0, -2.0};
const Pose2 kWrong{kFrameQ.x + 14.0, kFrameQ.y - 6.0, kFrameQ.theta + 0.3};  // a false placement of q

PeerState Peer(RobotId robot, const LandmarkMap& local, const Pose2& to_own) {
  PeerState p;
  p.key = {robot, 1};
  p.stage = PeerStage::kAligned;
  p.local = local;
  p.has_local = true;
  p.to_own = to_own;
  p.to_own_cov = 1e-4 * Eigen::Matrix3d::Identity();
  p.direct = MapSource{robot, 1, local, to_own, p.to_own_cov, false};
  p.source = p.direct;
  return p;
}

class RelayPolicyTest : public ::testing::Test {
 protected:
  World world{7};
  std::mt19937_64 rng{8};
  ExchangeOptions options;
  RelayPolicy policy{options};
};

TEST_F(RelayPolicyTest, TransformsAgreeWithinBothTolerancesAtThePoint) {
  const Pose2 a{3.0, -2.0, 0.4};
  const Eigen::Vector2d at(10.0, 0.0);
  EXPECT_TRUE(policy.Agree(a, a, at));
  EXPECT_TRUE(policy.Agree(a, Pose2{a.x + 0.9, a.y, a.theta}, at));
  EXPECT_FALSE(policy.Agree(a, Pose2{a.x + 1.1, a.y, a.theta}, at));
  // Turned by 1.5 degrees: 0.26 m off at 10 m, agree; by 2.5 degrees: beyond the angle tolerance.
  EXPECT_TRUE(policy.Agree(a, Pose2{a.x, a.y, a.theta + DegToRad(1.5)}, Eigen::Vector2d::Zero()));
  EXPECT_FALSE(policy.Agree(a, Pose2{a.x, a.y, a.theta + DegToRad(2.5)}, Eigen::Vector2d::Zero()));
  // The same turn about a point far from the map's centre moves it beyond the distance tolerance.
  EXPECT_FALSE(policy.Agree(a, Pose2{a.x, a.y, a.theta + DegToRad(1.5)}, Eigen::Vector2d(60.0, 0.0)));
}

TEST_F(RelayPolicyTest, CompareTellsAgreementDisagreementAndNoOverlap) {
  const LandmarkMap witness = world.Map(0.0, 26.0, Pose2{}, rng);  // in our frame
  const LandmarkMap map = world.Map(14.0, 40.0, kFrameP, rng);
  int inliers = -1;
  EXPECT_EQ(policy.Compare(witness, map, kFrameP, &inliers), RelayPolicy::Overlap::kAgrees);
  EXPECT_GE(inliers, options.align.min_inliers);
  EXPECT_EQ(policy.Compare(witness, map, Pose2{kFrameP.x + 5.0, kFrameP.y, kFrameP.theta}),
            RelayPolicy::Overlap::kDisagrees);
  const LandmarkMap far = world.Map(30.0, 40.0, kFrameP, rng);  // nothing of it in the witness's strip
  EXPECT_EQ(policy.Compare(witness, far, kFrameP), RelayPolicy::Overlap::kNone);
}

TEST_F(RelayPolicyTest, ARelayThatPlacesAnAlignedPeerElsewhereIsAConflict) {
  PeerStates peers;
  PeerState& q = peers[{3, 1}] = Peer(3, world.Map(20.0, 40.0, kFrameQ, rng), kFrameQ);
  PeerState& p = peers[{2, 1}] = Peer(2, world.Map(0.0, 20.0, kFrameP, rng), kFrameP);
  // p's global map holds q's strip as well, in p's frame.
  p.global = world.Map(0.0, 40.0, kFrameP, rng);
  p.has_global = true;
  EXPECT_EQ(policy.FirstConflict(peers, p, kFrameP), std::nullopt);
  // Placed elsewhere, p's global map no longer matches q's map where they overlap.
  const Pose2 off{kFrameP.x + 4.0, kFrameP.y - 3.0, kFrameP.theta};
  ASSERT_TRUE(policy.FirstConflict(peers, p, off).has_value());
  EXPECT_EQ(*policy.FirstConflict(peers, p, off), (PeerKey{3, 1}));
  // A frozen peer that this relay re-placed is the relay's to bring: no witness against it.
  q.superseded_by = p.key;
  EXPECT_EQ(policy.FirstConflict(peers, p, off), std::nullopt);
}

TEST_F(RelayPolicyTest, WeighCountsTheMapsThatSupportAndOpposeAPlacement) {
  const LandmarkMap own = world.Map(0.0, 26.0, Pose2{}, rng);
  PeerStates peers;
  PeerState& q = peers[{3, 1}] = Peer(3, world.Map(18.0, 40.0, kFrameQ, rng), kFrameQ);
  peers[{2, 1}] = Peer(2, world.Map(22.0, 40.0, kFrameP, rng), kFrameP);
  const RelayPolicy::Evidence right = policy.Weigh(peers, q, kFrameQ, own);
  EXPECT_EQ(right.supporters, 2);  // our own map and peer 2's
  EXPECT_EQ(right.against, 0);
  EXPECT_GT(right.inliers, 2 * options.align.min_inliers);
  const RelayPolicy::Evidence wrong = policy.Weigh(peers, q, Pose2{kFrameQ.x + 3.0, kFrameQ.y, kFrameQ.theta}, own);
  EXPECT_EQ(wrong.supporters, 0);
  EXPECT_EQ(wrong.against, 2);
  // Another incarnation of q's robot is no independent witness of it.
  peers[{3, 2}] = Peer(3, world.Map(18.0, 40.0, kFrameQ, rng), kFrameQ);
  EXPECT_EQ(policy.Weigh(peers, q, kFrameQ, own).supporters, 2);
}

TEST_F(RelayPolicyTest, ABetterSupportedRelayRefutesAFalseAlignmentAndOnlyThat) {
  const LandmarkMap own = world.Map(0.0, 30.0, Pose2{}, rng);
  PeerStates peers;
  // We placed q falsely; p's relay holds q's landmarks where they truly are.
  PeerState& q = peers[{3, 1}] = Peer(3, world.Map(20.0, 40.0, kFrameQ, rng), kWrong);
  PeerState& p = peers[{2, 1}] = Peer(2, world.Map(0.0, 20.0, kFrameP, rng), kFrameP);
  p.global = world.Map(0.0, 40.0, kFrameP, rng);
  p.has_global = true;
  std::mt19937_64 search(9);
  const auto refuted = policy.Refutation(peers, p, kFrameP, q, own, search);
  ASSERT_TRUE(refuted.has_value());
  EXPECT_TRUE(policy.Agree(refuted->transform, kFrameQ, Centroid(q.Map())));
  // Its covariance includes the relay's own placement.
  EXPECT_TRUE((refuted->cov - p.to_own_cov).diagonal().minCoeff() >= 0.0);

  // Where our alignment is right, the relay's placement (p placed falsely) refutes nothing.
  q.to_own = kFrameQ;
  q.direct->to_own = kFrameQ;
  const Pose2 p_wrong{kFrameP.x + 12.0, kFrameP.y + 8.0, kFrameP.theta - 0.4};
  EXPECT_EQ(policy.Refutation(peers, p, p_wrong, q, own, search), std::nullopt);
  // Two placements this close are two fits of one alignment, not a false one.
  const Pose2 p_near{kFrameP.x + 0.5, kFrameP.y, kFrameP.theta};
  EXPECT_EQ(policy.Refutation(peers, p, p_near, q, own, search), std::nullopt);
}

TEST_F(RelayPolicyTest, AFrozenPeerIsRefutedOnlyWhenAnotherMapSupportsTheRelay) {
  // Our own map sees nothing of q's strip, so no map but the relay says where q belongs.
  const LandmarkMap own = world.Map(0.0, 12.0, Pose2{}, rng);
  PeerStates peers;
  PeerState& q = peers[{3, 1}] = Peer(3, world.Map(26.0, 40.0, kFrameQ, rng), kWrong);
  q.stale = true;  // frozen: its writer is gone
  PeerState& p = peers[{2, 1}] = Peer(2, world.Map(0.0, 20.0, kFrameP, rng), kFrameP);
  p.global = world.Map(0.0, 40.0, kFrameP, rng);
  p.has_global = true;
  std::mt19937_64 search(10);
  EXPECT_EQ(policy.Refutation(peers, p, kFrameP, q, own, search), std::nullopt);
  // A third peer that maps q's strip supports the relay: the frozen map is moved there.
  peers[{4, 1}] = Peer(4, world.Map(24.0, 40.0, kFrameP, rng), kFrameP);
  EXPECT_TRUE(policy.Refutation(peers, p, kFrameP, peers.at({3, 1}), own, search).has_value());
}

}  // namespace
}  // namespace mapmesh
