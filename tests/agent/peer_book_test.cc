#include "agent/peer_book.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

LandmarkMap MapOf(int n) {
  LandmarkMap m;
  for (int i = 0; i < n; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(i);
    l.mean = Eigen::Vector2d(i, 2.0 * i);
    l.cov = 0.01 * Eigen::Matrix2d::Identity();
    m.landmarks.push_back(l);
  }
  return m;
}

using Receipt = PeerBook::Receipt;

TEST(PeerBook, VersionsMustGrowAndNotJumpAheadOfThePublisher) {
  ExchangeOptions o;
  PeerBook book(1, o);
  EXPECT_EQ(book.OnPeerMap(2, 1, MapKind::kLocal, 1, 0.5, MapOf(3), 10.0), Receipt::kAccepted);
  EXPECT_EQ(book.OnPeerMap(2, 1, MapKind::kLocal, 1, 0.5, MapOf(4), 11.0), Receipt::kStaleVersion);
  EXPECT_EQ(book.OnPeerMap(2, 1, MapKind::kLocal, 2, 0.5, MapOf(4), 11.0), Receipt::kAccepted);
  // The other kind counts apart; a version beyond what could have been published is refused.
  EXPECT_EQ(book.OnPeerMap(2, 1, MapKind::kGlobal, 1, 0.5, MapOf(6), 11.0), Receipt::kAccepted);
  EXPECT_EQ(book.OnPeerMap(2, 1, MapKind::kLocal, 1000000, 0.5, MapOf(4), 12.0), Receipt::kVersionJump);
  const std::vector<PeerReport> r = book.Reports(12.0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].local_landmarks, 4);
  EXPECT_EQ(r[0].global_landmarks, 6);
  EXPECT_DOUBLE_EQ(r[0].last_heard, 11.0);
  EXPECT_DOUBLE_EQ(r[0].origin_stamp, 0.5);
  EXPECT_EQ(r[0].stage, PeerStage::kUnaligned);
}

TEST(PeerBook, LivenessIsComputedWhenAskedNeverKept) {
  ExchangeOptions o;
  PeerBook book(1, o);
  book.OnPeerMap(2, 1, MapKind::kLocal, 1, 0.0, MapOf(3), 10.0);
  EXPECT_FALSE(book.Reports(10.0)[0].silent);
  EXPECT_TRUE(book.Reports(10.0 + o.SilentAfterS() + 1.0)[0].silent);  // no map for silent_after_s
  EXPECT_FALSE(book.Reports(10.0)[0].silent);                          // ... asked again at 10 s
  // Lockstep: a tick's list without it makes it stale from then on; back in a list, live again.
  book.SetLive({}, 20.0);
  PeerReport r = book.Reports(20.0)[0];
  EXPECT_TRUE(r.stale && r.frozen && r.silent);
  EXPECT_DOUBLE_EQ(r.stale_since, 20.0);
  book.SetLive({}, 25.0);
  EXPECT_DOUBLE_EQ(book.Reports(25.0)[0].stale_since, 20.0);  // since it went, not since last told
  EXPECT_EQ(book.StaleRobots(), std::vector<RobotId>{2});
  book.SetLive({{2, 1}}, 30.0);
  EXPECT_FALSE(book.Reports(30.0)[0].stale);
  // Liveliness (realtime) speaks for every incarnation of the robot; a map heard revives it.
  book.OnPeerMap(2, 2, MapKind::kLocal, 1, 0.0, MapOf(3), 31.0);
  book.OnPeerLiveliness(2, false, 32.0);
  EXPECT_EQ(book.StaleRobots(), std::vector<RobotId>{2});
  EXPECT_TRUE(book.Reports(32.0)[1].stale);
  book.OnPeerMap(2, 2, MapKind::kLocal, 2, 0.0, MapOf(3), 33.0);
  EXPECT_FALSE(book.Reports(33.0)[1].stale);
  EXPECT_TRUE(book.Reports(33.0)[0].stale);
}

TEST(PeerBook, AnEarlierOwnIncarnationIsFrozenAndCarriedOnUntilAligned) {
  ExchangeOptions o;
  PeerBook book(1, o);
  book.AddOwnCheckpoint(1, 0.5, MapOf(5), MapOf(8));
  const PeerReport r = book.Reports(0.0)[0];
  EXPECT_TRUE(r.own_checkpoint && r.frozen && r.stale);
  EXPECT_EQ(r.local_landmarks, 5);
  EXPECT_EQ(r.global_landmarks, 8);
  ASSERT_EQ(book.UnalignedOwnCheckpoints().size(), 1u);
  EXPECT_TRUE(book.ReceivedMaps().empty());  // not a peer's map
  EXPECT_TRUE(book.StaleRobots().empty());
  // Liveliness never revives it: that process is gone.
  book.OnPeerLiveliness(1, true, 1.0);
  book.SetLive({{1, 1}}, 1.0);
  EXPECT_TRUE(book.Reports(1.0)[0].frozen);
  // Once it is placed (MapExchange chose a source of it), a checkpoint need not carry it on.
  book.states().at({1, 1}).source = MapSource{};
  EXPECT_TRUE(book.UnalignedOwnCheckpoints().empty());
}

TEST(PeerBook, IncarnationsAreBoundedAndOnlyThoseThatGaveNothingAreEvicted) {
  ExchangeOptions o;
  o.max_incarnations = 2;
  PeerBook book(1, o);
  ASSERT_EQ(book.OnPeerMap(2, 1, MapKind::kLocal, 1, 0.0, MapOf(3), 1.0), Receipt::kAccepted);
  ASSERT_EQ(book.OnPeerMap(2, 2, MapKind::kLocal, 1, 0.0, MapOf(3), 2.0), Receipt::kAccepted);
  // Both still speak: a third has no room.
  EXPECT_EQ(book.OnPeerMap(2, 3, MapKind::kLocal, 1, 0.0, MapOf(3), 3.0), Receipt::kTooManyIncarnations);
  // Incarnation 1 contributed once (ever aligned) and both went silent: the other one goes.
  book.states().at({2, 1}).ever_aligned = true;
  book.OnPeerLiveliness(2, false, 4.0);
  EXPECT_EQ(book.OnPeerMap(2, 3, MapKind::kLocal, 1, 0.0, MapOf(3), 5.0), Receipt::kAccepted);
  ASSERT_EQ(book.states().size(), 2u);
  EXPECT_TRUE(book.states().count({2, 1}));
  EXPECT_TRUE(book.states().count({2, 3}));
  // Other robots are not counted against robot 2.
  EXPECT_EQ(book.OnPeerMap(3, 1, MapKind::kLocal, 1, 0.0, MapOf(3), 5.0), Receipt::kAccepted);
}

TEST(PeerBook, FactsSayWhatTheScheduleReads) {
  ExchangeOptions o;
  PeerBook book(1, o);
  book.OnPeerMap(2, 1, MapKind::kLocal, 1, 0.0, MapOf(7), 1.0);
  book.OnPeerMap(2, 1, MapKind::kGlobal, 1, 0.0, MapOf(12), 1.0);
  PeerState& p = book.states().at({2, 1});
  p.stage = PeerStage::kAligned;
  p.aligned_by = AlignmentSource::kOverlap;
  p.relay_judged = true;
  p.relay_judged_version = 1;
  p.relay_judged_size = 9;
  const PeerFacts f = book.Facts(1.0).at(0);
  EXPECT_TRUE(f.has_map && f.aligned && f.aligned_by_overlap && f.changed && f.has_global && f.global_judged);
  EXPECT_FALSE(f.stale || f.silent || f.awaiting_confirmation || f.rendezvous_waiting || f.global_newer);
  EXPECT_EQ(f.map_size, 7u);
  EXPECT_EQ(f.global_growth, 3);
  book.OnPeerMap(2, 1, MapKind::kGlobal, 2, 0.0, MapOf(15), 2.0);
  EXPECT_TRUE(book.Facts(2.0).at(0).global_newer);
  EXPECT_TRUE(book.Facts(2.0 + o.SilentAfterS() + 1.0).at(0).silent);
}

// A later incarnation that began at the same origin stamp (its stream replayed) carries an
// earlier one's map once it holds as many landmarks; one that began elsewhere never does.
TEST(PeerBook, ALaterIncarnationInTheSameFrameCarriesAnEarlierOnceItHoldsAsMuch) {
  ExchangeOptions o;
  PeerBook book(1, o);
  auto carried = [&](std::uint32_t incarnation) {
    for (const PeerFacts& f : book.Facts(10.0))
      if (f.key == PeerKey{2, incarnation}) return f.carried;
    ADD_FAILURE() << "no incarnation " << incarnation;
    return false;
  };
  book.OnPeerMap(2, 1, MapKind::kLocal, 1, 0.5, MapOf(8), 1.0);
  EXPECT_FALSE(carried(1));
  book.OnPeerMap(2, 2, MapKind::kLocal, 1, 0.5, MapOf(5), 2.0);  // replaying: not yet
  EXPECT_FALSE(carried(1));
  EXPECT_FALSE(carried(2));
  book.OnPeerMap(2, 2, MapKind::kLocal, 2, 0.5, MapOf(8), 3.0);
  EXPECT_TRUE(carried(1));
  EXPECT_FALSE(carried(2));                                       // the latest is never carried
  book.OnPeerMap(2, 3, MapKind::kLocal, 1, 7.5, MapOf(20), 4.0);  // another frame (stream not kept)
  EXPECT_TRUE(carried(1));
  EXPECT_FALSE(carried(2));
  book.OnPeerMap(3, 1, MapKind::kLocal, 1, 0.5, MapOf(20), 4.0);  // another robot
  EXPECT_FALSE(carried(2));
}

// A checkpoint's peers' frames (issue R3): nothing waits on them until this session's frame is
// the one they were placed in; then each peer incarnation of the same robot and frame that is
// not aligned waits to weigh the newest one, up to its incarnation, whatever align_by says; a
// new checkpoint carries on those not placed again, and the aligned peers' own.
TEST(PeerBook, CarriedAlignmentsWaitForTheirFrameThenSeedTheSameFramesPeers) {
  ExchangeOptions o;
  o.align_by = AlignBy::kOverlap;
  PeerBook book(1, o);
  PeerAlignment a;
  a.robot = 2;
  a.incarnation = 1;
  a.origin_stamp = 0.5;
  a.frame_stamp = 0.2;
  a.to_own = {4.0, -2.0, 0.3};
  a.cov = 1e-3 * Eigen::Matrix3d::Identity();
  PeerAlignment newer = a;
  newer.incarnation = 2;
  newer.to_own = {4.5, -2.0, 0.3};
  PeerAlignment elsewhere = a;  // robot 3, in a frame this session is not in
  elsewhere.robot = 3;
  elsewhere.frame_stamp = 9.0;
  PeerAlignment own = a;  // never the agent's own robot
  own.robot = 1;
  book.AddCarried({a, newer, elsewhere, own});
  const auto waiting = [&](PeerKey key) {
    for (const PeerFacts& f : book.Facts(10.0))
      if (f.key == key) return f.continuity_waiting && f.rendezvous_waiting;
    return false;
  };
  book.OnPeerMap(2, 2, MapKind::kLocal, 1, 0.5, MapOf(5), 1.0);
  EXPECT_FALSE(waiting({2, 2}));  // the frame is not known to be this session's yet
  EXPECT_EQ(book.UseCarriedIn(0.2), 1);
  EXPECT_TRUE(waiting({2, 2}));
  ASSERT_TRUE(book.states().at({2, 2}).rendezvous.has_value());
  EXPECT_EQ(book.states().at({2, 2}).rendezvous->transform.x, 4.5);  // the newest up to its incarnation
  // A later incarnation of the robot in the same frame takes it as it arrives; one in another
  // frame (its stream was not kept) does not, nor another robot's in a frame not ours.
  book.OnPeerMap(2, 4, MapKind::kLocal, 1, 0.5, MapOf(5), 2.0);
  book.OnPeerMap(2, 5, MapKind::kLocal, 1, 7.0, MapOf(5), 2.0);
  book.OnPeerMap(3, 1, MapKind::kLocal, 1, 0.5, MapOf(5), 2.0);
  EXPECT_TRUE(waiting({2, 4}));
  EXPECT_FALSE(waiting({2, 5}));
  EXPECT_FALSE(waiting({3, 1}));
  // Nothing aligned yet: a new checkpoint carries every one on (none of the own robot).
  std::vector<PeerAlignment> kept = book.Alignments(0.2);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[0].incarnation, 1u);
  EXPECT_EQ(kept[2].robot, 3u);
  PeerState& p = book.states().at({2, 2});
  p.stage = PeerStage::kAligned;
  p.to_own = {4.6, -2.1, 0.31};
  p.to_own_cov = 2e-3 * Eigen::Matrix3d::Identity();
  kept = book.Alignments(0.7);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[0].robot, 2u);  // the aligned one first, in this session's frame
  EXPECT_EQ(kept[0].incarnation, 2u);
  EXPECT_EQ(kept[0].frame_stamp, 0.7);
  EXPECT_EQ(kept[0].to_own.x, 4.6);
  EXPECT_EQ(kept[1].incarnation, 1u);  // the carried ones not aligned now, in theirs
  EXPECT_EQ(kept[1].frame_stamp, 0.2);
  EXPECT_EQ(kept[2].robot, 3u);
}

}  // namespace
}  // namespace mapmesh
