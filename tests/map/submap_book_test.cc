#include "common/map/submap_book.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "tests/testing/small_submap.h"

namespace mapmesh {
namespace {

WireSubmap Submap(RobotId robot, std::uint32_t incarnation, std::uint32_t index, double x = 1.0) {
  return testing::SmallSubmap(robot, incarnation, index, x);
}

// A submap enters once however often it arrives; a different one under a held identity is
// refused and counted, and the first stays.
TEST(SubmapBook, EachIdentityEntersOnceAndAConflictIsRefused) {
  SubmapBook book;
  const WireSubmap a = Submap(2, 1, 0);
  const std::vector<std::uint8_t> a_bytes = EncodeSubmap(a);
  EXPECT_EQ(book.Add(a, a_bytes), SubmapBook::Offer::kNew);
  EXPECT_EQ(book.Add(a, a_bytes), SubmapBook::Offer::kDuplicate);  // relayed again
  const WireSubmap forged = Submap(2, 1, 0, 5.0);
  EXPECT_EQ(book.Add(forged, EncodeSubmap(forged)), SubmapBook::Offer::kConflict);
  EXPECT_EQ(book.size(), 1u);
  EXPECT_EQ(book.duplicates(), 1);
  EXPECT_EQ(book.conflicts(), 1);
  ASSERT_NE(book.Find({2, 1, 0}), nullptr);
  EXPECT_EQ(book.Find({2, 1, 0})->x, a.x);
  EXPECT_EQ(book.bytes(), a_bytes.size());
  EXPECT_EQ(book.Find({2, 1, 1}), nullptr);
  ASSERT_NE(book.Bytes({2, 1, 0}), nullptr);
  EXPECT_EQ(*book.Bytes({2, 1, 0}), a_bytes);  // what a relay sends on: the first one's bytes
  EXPECT_EQ(book.Bytes({2, 1, 1}), nullptr);
}

// The chain a receiver can use: held from index 0 without a gap, per robot incarnation.
TEST(SubmapBook, ChainLengthStopsAtTheFirstGap) {
  SubmapBook book;
  for (std::uint32_t i : {0u, 1u, 3u}) {
    const WireSubmap s = Submap(4, 2, i);
    book.Add(s, EncodeSubmap(s));
  }
  const WireSubmap other = Submap(4, 3, 0);
  book.Add(other, EncodeSubmap(other));
  EXPECT_EQ(book.ChainLength(4, 2), 2u);
  EXPECT_EQ(book.ChainLength(4, 3), 1u);
  EXPECT_EQ(book.ChainLength(4, 1), 0u);
  EXPECT_EQ(book.ChainLength(5, 2), 0u);
  const WireSubmap gap = Submap(4, 2, 2);
  book.Add(gap, EncodeSubmap(gap));
  EXPECT_EQ(book.ChainLength(4, 2), 4u);
  const std::vector<SubmapId> ids = book.Ids();
  ASSERT_EQ(ids.size(), 5u);
  EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end()));
  // One chain per robot incarnation held, a chain without its first submap of length 0; the
  // largest identities too.
  const WireSubmap late = Submap(6, 1, 2);
  book.Add(late, EncodeSubmap(late));
  const WireSubmap last = Submap(UINT32_MAX, UINT32_MAX, UINT32_MAX);
  book.Add(last, EncodeSubmap(last));
  EXPECT_EQ(book.Chains(), (std::vector<SubmapChain>{{4, 2, 4}, {4, 3, 1}, {6, 1, 0}, {UINT32_MAX, UINT32_MAX, 0}}));
}

// A submap of (robot, incarnation, index) opened at `from` and closed at `to`, into the book.
void AddSpanning(SubmapBook& book, RobotId robot, std::uint32_t incarnation, std::uint32_t index, double from,
                 double to) {
  WireSubmap s = Submap(robot, incarnation, index);
  s.opened_s = from;
  s.closed_s = to;
  book.Add(s, EncodeSubmap(s));
}

// A later incarnation that maps the same time again (a lockstep restart replays the robot's
// stream from the start) supersedes the earlier; one that begins after the earlier's last
// submap does not, nor does another robot's chain at the same time. Open submaps count.
TEST(SubmapBook, AnIncarnationWhoseTimeALaterOneMapsAgainIsSuperseded) {
  SubmapBook book;
  const auto add = [&](RobotId robot, std::uint32_t incarnation, std::uint32_t index, double from, double to) {
    AddSpanning(book, robot, incarnation, index, from, to);
  };
  add(3, 1, 0, 0.5, 30.0);
  add(3, 1, 1, 30.0, 58.0);
  add(5, 1, 0, 0.5, 40.0);  // another robot, the same time
  EXPECT_TRUE(book.Superseded().empty());
  add(3, 2, 0, 80.0, 95.0);  // a restart that takes the stream where it is
  EXPECT_TRUE(book.Superseded().empty());
  WireSubmap replay = Submap(3, 3, 0);  // a third incarnation replaying from the start, still open
  replay.opened_s = 0.5;
  replay.closed_s = 12.0;
  const WireSubmap* open[] = {&replay, nullptr};
  using Chains = std::set<std::pair<RobotId, std::uint32_t>>;
  EXPECT_EQ(book.Superseded(open), (Chains{{3, 1}}));  // 3.2 begins after 12 s
  replay.closed_s = 85.0;
  EXPECT_EQ(book.Superseded(open), (Chains{{3, 1}, {3, 2}}));
  add(5, 4, 0, 39.0, 41.0);
  EXPECT_EQ(book.Superseded(open), (Chains{{3, 1}, {3, 2}, {5, 1}}));
}

// Issue R3: submaps relabelled under an incarnation that never ran (a ghost) left robot 3's
// real chain out of every join. With the incarnations heard, only a heard one supersedes; of
// an overlapping pair whose later one is not heard, the later one is left out.
TEST(SubmapBook, OnlyAnIncarnationHeardSupersedes) {
  SubmapBook book;
  const auto add = [&](RobotId robot, std::uint32_t incarnation, std::uint32_t index, double from, double to) {
    AddSpanning(book, robot, incarnation, index, from, to);
  };
  using Chains = std::set<std::pair<RobotId, std::uint32_t>>;
  add(3, 1, 0, 0.5, 30.0);
  add(3, 1, 1, 30.0, 58.0);
  add(3, 77, 0, 0.5, 30.0);  // robot 3's submap as a ghost's
  Chains heard = {{3, 1}};
  EXPECT_EQ(book.Superseded({}, &heard), (Chains{{3, 77}}));
  EXPECT_EQ(book.Superseded({}), (Chains{{3, 1}}));  // without the facts: what the ghost did
  // A restart replaying from the start, heard: it supersedes both.
  add(3, 2, 0, 0.5, 20.0);
  heard.insert({3, 2});
  EXPECT_EQ(book.Superseded({}, &heard), (Chains{{3, 1}, {3, 77}}));
  // Incarnation 2 heard no longer (a restarted agent has heard no one yet): 1 stays, 2 and the
  // ghost do not.
  heard = {{3, 1}};
  EXPECT_EQ(book.Superseded({}, &heard), (Chains{{3, 2}, {3, 77}}));
  // Nothing heard: of every overlapping pair the later one goes, the earliest chain stays.
  heard.clear();
  EXPECT_EQ(book.Superseded({}, &heard), (Chains{{3, 2}, {3, 77}}));
}

}  // namespace
}  // namespace mapmesh
