#include "common/merge/chain_map.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <limits>
#include <random>
#include <set>
#include <vector>

#include "tests/testing/submap_world.h"

namespace mapmesh {
namespace {

using testing::Drive;
using testing::MeasureAll;
using testing::Pointers;
using testing::TrueChain;
using testing::World;

// Without noise the rebuilt map is the world, in the chain's first frame, every landmark once by
// its key.
TEST(ChainMap, ANoiseFreeChainGivesTheWorldInItsFirstFrame) {
  const World w(8, 2.0);
  std::mt19937_64 rng(1);
  const TrueChain t = Drive(w, Pose2{1.0, 1.0, 0.1}, 5, 3.0);
  std::vector<WireSubmap> subs = MeasureAll(w, t, 4, rng);
  for (std::size_t k = 0; k < subs.size(); ++k) {
    std::vector<Eigen::Vector2d> points;
    for (int i : t.seen[k]) points.push_back(w.landmarks[static_cast<std::size_t>(i)]);
    subs[k].x = PredictSubmap(t.frames[k], t.frames[k + 1], points);
  }
  ChainMap chain;
  EXPECT_TRUE(chain.map().empty());
  EXPECT_EQ(chain.Extend(Pointers(subs)), 5u);
  EXPECT_EQ(chain.joined(), 5u);
  std::set<std::uint32_t> expected;
  for (const auto& seen : t.seen) expected.insert(seen.begin(), seen.end());
  ASSERT_EQ(chain.map().size(), expected.size());
  for (const Landmark& l : chain.map().landmarks) {
    EXPECT_TRUE(expected.count(l.id));
    EXPECT_EQ(l.signature, -1);
    EXPECT_TRUE(IsValidCovariance(l.cov));
    EXPECT_LT((l.mean - t.frames[0].TransformTo(w.landmarks[l.id])).norm(), 1e-6);
  }
  EXPECT_GT(chain.map().shape_sigma_m, 0.0);
}

// Submaps joined as they arrive give the map joined at once; a chain with nothing new joins
// nothing.
TEST(ChainMap, ExtendingSubmapBySubmapIsJoiningThemAtOnce) {
  const World w(10, 2.0);
  std::mt19937_64 rng(2);
  const TrueChain t = Drive(w, Pose2{0.5, 2.0, -0.2}, 6, 3.0);
  const std::vector<WireSubmap> subs = MeasureAll(w, t, 2, rng);
  const std::vector<const WireSubmap*> all = Pointers(subs);
  JoinerOptions o;
  o.window = 2;  // the older submaps are marginalised
  ChainMap at_once(o), one_by_one(o);
  EXPECT_EQ(at_once.Extend(all), 6u);
  for (std::size_t n = 1; n <= all.size(); ++n) {
    EXPECT_EQ(one_by_one.Extend(std::span(all).first(n)), 1u);
    EXPECT_EQ(one_by_one.Extend(std::span(all).first(n)), 0u);
  }
  ASSERT_EQ(at_once.map().size(), one_by_one.map().size());
  for (std::size_t i = 0; i < at_once.map().size(); ++i) {
    EXPECT_EQ(at_once.map().landmarks[i].id, one_by_one.map().landmarks[i].id);
    EXPECT_EQ(at_once.map().landmarks[i].mean, one_by_one.map().landmarks[i].mean);
    EXPECT_EQ(at_once.map().landmarks[i].cov, one_by_one.map().landmarks[i].cov);
  }
}

// The rebuilt map is consistent: over seeded chains its landmarks' NEES against the truth (in
// the first frame) averages 2, the dimension.
TEST(ChainMap, TheRebuiltMapIsConsistent) {
  const World w(10, 2.0);
  double sum = 0.0;
  int n = 0;
  for (int seed = 0; seed < 40; ++seed) {
    std::mt19937_64 rng(100 + seed);
    const TrueChain t = Drive(w, Pose2{1.0, 1.5, 0.05}, 5, 3.0);
    const std::vector<WireSubmap> subs = MeasureAll(w, t, 3, rng);
    ChainMap chain;
    chain.Extend(Pointers(subs));
    for (const Landmark& l : chain.map().landmarks) {
      const Eigen::Vector2d e = l.mean - t.frames[0].TransformTo(w.landmarks[l.id]);
      sum += e.dot(l.cov.ldlt().solve(e));
      ++n;
    }
  }
  ASSERT_GT(n, 1000);
  EXPECT_GT(sum / n, 1.7);
  EXPECT_LT(sum / n, 2.3);
}

// A submap the joiner refuses ends the chain there: what came before stays, nothing after joins.
TEST(ChainMap, AMalformedSubmapEndsTheChain) {
  const World w(8, 2.0);
  std::mt19937_64 rng(4);
  const TrueChain t = Drive(w, Pose2{1.0, 1.0, 0.1}, 4, 3.0);
  std::vector<WireSubmap> subs = MeasureAll(w, t, 1, rng);
  const std::vector<const WireSubmap*> good = Pointers(subs);
  ChainMap two;
  two.Extend(std::span(good).first(2));
  subs[2].x(0) = std::numeric_limits<double>::quiet_NaN();
  ChainMap chain;
  EXPECT_EQ(chain.Extend(Pointers(subs)), 2u);
  EXPECT_TRUE(chain.broken());
  EXPECT_EQ(chain.joined(), 2u);
  EXPECT_EQ(chain.map().size(), two.map().size());
  EXPECT_EQ(chain.Extend(Pointers(subs)), 0u);
  EXPECT_FALSE(two.broken());
}

// A chain's open submap (relayed when its robot fell silent) joins after the closed ones: the
// map is the one joining it as the next submap gives, the chain itself is unchanged, and an
// open submap that does not continue the chain, or is malformed, leaves the closed ones' map.
TEST(ChainMap, AnOpenSubmapJoinsAfterTheClosedOnesWithoutChangingTheChain) {
  const World w(10, 2.0);
  std::mt19937_64 rng(5);
  const TrueChain t = Drive(w, Pose2{0.5, 1.0, 0.1}, 5, 3.0);
  const std::vector<WireSubmap> subs = MeasureAll(w, t, 2, rng);
  const std::vector<const WireSubmap*> all = Pointers(subs);
  ChainMap four, five;
  four.Extend(std::span(all).first(4));
  five.Extend(all);
  EXPECT_EQ(&four.MapWith(nullptr), &four.map());
  const LandmarkMap with = four.MapWith(all[4]);
  EXPECT_EQ(four.joined(), 4u);
  ASSERT_EQ(with.size(), five.map().size());
  EXPECT_GT(with.size(), four.map().size());
  for (std::size_t i = 0; i < with.size(); ++i) {
    EXPECT_EQ(with.landmarks[i].id, five.map().landmarks[i].id);
    EXPECT_LT((with.landmarks[i].mean - five.map().landmarks[i].mean).norm(), 1e-9);
    EXPECT_LT((with.landmarks[i].cov - five.map().landmarks[i].cov).norm(), 1e-9);
  }
  // Asked again for the same version of the open submap (identity and end): the map kept, not
  // solved again (this copy's moved landmarks would move the map).
  WireSubmap same = subs[4];
  same.x.tail(same.x.size() - 3).array() += 1.0;
  const LandmarkMap& kept = four.MapWith(&same);
  ASSERT_EQ(kept.size(), with.size());
  for (std::size_t i = 0; i < with.size(); ++i) EXPECT_EQ(kept.landmarks[i].mean, with.landmarks[i].mean);
  same.closed_s += 1.0;  // a later version: solved again
  const LandmarkMap& later = four.MapWith(&same);
  ASSERT_EQ(later.size(), with.size());
  double moved = 0.0;
  for (std::size_t i = 0; i < with.size(); ++i)
    moved = std::max(moved, (later.landmarks[i].mean - with.landmarks[i].mean).norm());
  EXPECT_GT(moved, 1e-3);  // the kept one was equal to the digit
  // Not the chain's next submap: the closed ones' map.
  EXPECT_EQ(&four.MapWith(all[3]), &four.map());
  EXPECT_EQ(&five.MapWith(all[4]), &five.map());
  WireSubmap bad = subs[4];
  bad.x(0) = std::numeric_limits<double>::quiet_NaN();
  bad.closed_s += 2.0;  // a later version of it, malformed
  EXPECT_EQ(&four.MapWith(&bad), &four.map());
  EXPECT_FALSE(four.broken());
  // With none closed, the chain's first submap open: its map alone, as once closed.
  ChainMap none, first;
  first.Extend(std::span(all.data(), 1));
  const LandmarkMap& alone = none.MapWith(all[0]);
  ASSERT_EQ(alone.size(), first.map().size());
  ASSERT_GT(alone.size(), 0u);
  for (std::size_t i = 0; i < alone.size(); ++i) {
    EXPECT_EQ(alone.landmarks[i].id, first.map().landmarks[i].id);
    EXPECT_LT((alone.landmarks[i].mean - first.map().landmarks[i].mean).norm(), 1e-9);
  }
  EXPECT_EQ(&none.MapWith(all[1]), &none.map());  // not the chain's first
}

}  // namespace
}  // namespace mapmesh
