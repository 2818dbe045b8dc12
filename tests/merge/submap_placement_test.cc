#include "common/merge/submap_placement.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>
#include <set>
#include <vector>

#include "common/solver/chi2.h"
#include "tests/testing/submap_world.h"

namespace mapmesh {
namespace {

using testing::Drive;
using testing::MeasureAll;
using testing::Pointers;
using testing::TrueChain;
using testing::World;

// The world's landmarks as the holder's map (the own frame is the world's), each known to
// sigma.
LandmarkMap Target(const World& w, double sigma, const std::set<int>& leave_out = {}) {
  LandmarkMap m;
  for (std::size_t i = 0; i < w.landmarks.size(); ++i) {
    if (leave_out.contains(static_cast<int>(i))) continue;
    m.landmarks.push_back({static_cast<std::uint32_t>(1000 + i), -1, w.landmarks[i],
                           sigma * sigma * Eigen::Matrix2d::Identity()});
  }
  return m;
}

// Noise-free submaps whose end poses are each turned by `bend` (rad): joined along the chain
// their map bends, while each submap's landmarks are exact in its own frame.
std::vector<WireSubmap> BentChain(const World& w, const TrueChain& t, double bend, std::mt19937_64& rng) {
  std::vector<WireSubmap> subs = MeasureAll(w, t, 4, rng);
  for (std::size_t k = 0; k < subs.size(); ++k) {
    std::vector<Eigen::Vector2d> points;
    for (int i : t.seen[k]) points.push_back(w.landmarks[static_cast<std::size_t>(i)]);
    subs[k].x = PredictSubmap(t.frames[k], t.frames[k + 1], points);
    subs[k].x(2) += bend;
  }
  return subs;
}

// The peer's whole map, exact in its first frame, at its true placement: the landmarks its
// submaps hold and `extra` ones.
MapSource WholeMap(const World& w, const TrueChain& t, const std::vector<WireSubmap>& subs,
                   const std::set<std::uint32_t>& extra = {}) {
  MapSource whole{4, 1, {}, t.frames[0], 1e-4 * Eigen::Matrix3d::Identity(), false};
  std::set<std::uint32_t> ids = extra;
  for (const WireSubmap& s : subs) ids.insert(s.keys.begin(), s.keys.end());
  for (const std::uint32_t id : ids) {
    whole.map.landmarks.push_back({id, -1, t.frames[0].TransformTo(w.landmarks[id]),
                                   0.01 * Eigen::Matrix2d::Identity()});
  }
  return whole;
}

double PlacementError(const Pose2& a, const Pose2& b) {
  return std::max(std::hypot(a.x - b.x, a.y - b.y), std::abs(WrapAngle(a.theta - b.theta)));
}

// A bent chain: along the chain the submaps drift off their places (0.05 rad per submap); each
// placed on its own lands at its true frame, and its landmarks on the world's.
TEST(PlaceSubmapsPiecewise, EachSubmapOfABentChainLandsWhereItIs) {
  const World w(12, 2.0);
  std::mt19937_64 rng(3);
  const TrueChain t = Drive(w, Pose2{2.0, 2.0, 0.1}, 5, 3.0);
  const std::vector<WireSubmap> subs = BentChain(w, t, 0.05, rng);
  const MapSource whole{4, 1, {}, t.frames[0], 1e-4 * Eigen::Matrix3d::Identity(), false};
  PiecewiseStats stats;
  const std::vector<MapSource> placed = PlaceSubmapsPiecewise(Target(w, 0.02), whole, Pointers(subs), {}, &stats);
  ASSERT_EQ(placed.size(), subs.size());  // the whole map is empty: no rest
  EXPECT_EQ(stats.submaps, 5);
  EXPECT_EQ(stats.fitted, 5);
  EXPECT_EQ(stats.chained, 0);
  EXPECT_EQ(stats.rest, 0);
  Pose2 chained = t.frames[0];
  for (std::size_t k = 0; k < subs.size(); ++k) {
    EXPECT_EQ(placed[k].robot, 4u);
    EXPECT_EQ(placed[k].incarnation, 1u);
    EXPECT_LT(PlacementError(placed[k].to_own, t.frames[k]), 1e-9) << k;
    ASSERT_EQ(placed[k].map.size(), subs[k].keys.size());
    for (std::size_t i = 0; i < subs[k].keys.size(); ++i) {
      const Landmark& l = placed[k].map.landmarks[i];
      EXPECT_EQ(l.id, subs[k].keys[i]);
      EXPECT_LT((placed[k].to_own.Apply(l.mean) - w.landmarks[l.id]).norm(), 1e-9);
    }
    // Along the chain alone it would be off by the bend.
    if (k >= 2) {
      EXPECT_GT(PlacementError(chained, t.frames[k]), 0.05) << k;
    }
    chained = chained * Pose2{subs[k].x(0), subs[k].x(1), subs[k].x(2)};
  }
}

// Where neither the target nor the whole map holds a submap's landmarks, the submap is placed
// along the chain: the previous placement composed with its end pose, the covariance grown by
// the end pose's.
TEST(PlaceSubmapsPiecewise, ASubmapOverNoTargetLandmarksFollowsTheChain) {
  const World w(12, 2.0);
  std::mt19937_64 rng(4);
  const TrueChain t = Drive(w, Pose2{2.0, 2.0, 0.1}, 4, 3.0);
  const std::vector<WireSubmap> subs = BentChain(w, t, 0.0, rng);
  // The target lacks every landmark only the last submap holds, and all but two of those it
  // shares with the others.
  std::set<int> out(t.seen[3].begin(), t.seen[3].end());
  const MapSource whole{4, 1, {}, t.frames[0], 1e-4 * Eigen::Matrix3d::Identity(), false};
  PiecewiseStats stats;
  const std::vector<MapSource> placed = PlaceSubmapsPiecewise(Target(w, 0.02, out), whole, Pointers(subs), {}, &stats);
  ASSERT_EQ(placed.size(), 4u);
  EXPECT_EQ(stats.fitted, 3);
  EXPECT_EQ(stats.chained, 1);
  Eigen::Matrix3d ja, jb;
  const WireSubmap& prev = subs[2];
  const Eigen::Matrix3d end_cov = prev.Covariance().topLeftCorner(3, 3);
  const Pose2 expect = Compose(placed[2].to_own, Pose2{prev.x(0), prev.x(1), prev.x(2)}, &ja, &jb);
  EXPECT_LT(PlacementError(placed[3].to_own, expect), 1e-12);
  const Eigen::Matrix3d expect_cov = ja * placed[2].to_own_cov * ja.transpose() + jb * end_cov * jb.transpose();
  EXPECT_LT((placed[3].to_own_cov - expect_cov).norm(), 1e-12);
  EXPECT_GT(placed[3].to_own_cov.trace(), placed[2].to_own_cov.trace());
  EXPECT_LT(PlacementError(placed[3].to_own, t.frames[3]), 1e-9);  // the chain is exact here
}

// Where the target holds none of a submap's landmarks but the peer's whole map does, the submap
// lies where that map puts it relative to the last fitted submap: exact with an exact joined map,
// where the end poses (each turned by 0.05 rad) would put it off.
TEST(PlaceSubmapsPiecewise, ASubmapOverNoTargetLandmarksLiesWhereTheWholeMapPutsIt) {
  const World w(12, 2.0);
  std::mt19937_64 rng(8);
  const TrueChain t = Drive(w, Pose2{2.0, 2.0, 0.1}, 4, 3.0);
  const std::vector<WireSubmap> subs = BentChain(w, t, 0.05, rng);
  const MapSource whole = WholeMap(w, t, subs);
  const std::set<int> out(t.seen[3].begin(), t.seen[3].end());
  PiecewiseStats stats;
  const std::vector<MapSource> placed = PlaceSubmapsPiecewise(Target(w, 0.02, out), whole, Pointers(subs), {}, &stats);
  ASSERT_EQ(placed.size(), 4u);  // every landmark of the whole map is in a submap
  EXPECT_EQ(stats.fitted, 3);
  EXPECT_EQ(stats.chained, 1);
  EXPECT_LT(PlacementError(placed[3].to_own, t.frames[3]), 1e-9);
  const Pose2 by_end_pose = placed[2].to_own * Pose2{subs[2].x(0), subs[2].x(1), subs[2].x(2)};
  EXPECT_GT(PlacementError(by_end_pose, t.frames[3]), 0.04);
}

// The whole map's landmarks that no submap holds (the open submap not given) follow as one more
// source at the whole map's alignment.
TEST(PlaceSubmapsPiecewise, LandmarksNoSubmapHoldsFollowAtTheAlignment) {
  const World w(12, 2.0);
  std::mt19937_64 rng(5);
  const TrueChain t = Drive(w, Pose2{2.0, 2.0, 0.1}, 3, 3.0);
  const std::vector<WireSubmap> subs = BentChain(w, t, 0.0, rng);
  std::set<std::uint32_t> held;
  for (const WireSubmap& s : subs) held.insert(s.keys.begin(), s.keys.end());
  std::set<std::uint32_t> extra;
  for (std::uint32_t id : {3u, 77u, 140u}) {
    if (!held.contains(id)) extra.insert(id);
  }
  ASSERT_FALSE(extra.empty());
  const MapSource whole = WholeMap(w, t, subs, extra);
  PiecewiseStats stats;
  const std::vector<MapSource> placed = PlaceSubmapsPiecewise(Target(w, 0.02), whole, Pointers(subs), {}, &stats);
  ASSERT_EQ(placed.size(), subs.size() + 1);
  const MapSource& rest = placed.back();
  EXPECT_EQ(static_cast<int>(rest.map.size()), stats.rest);
  EXPECT_EQ(rest.map.size() + held.size(), whole.map.size());
  for (const Landmark& l : rest.map.landmarks) EXPECT_FALSE(held.contains(l.id));
  EXPECT_EQ(rest.to_own.Vector(), whole.to_own.Vector());
  EXPECT_EQ(rest.to_own_cov, whole.to_own_cov);
  // No chain: the whole map as it is.
  const std::vector<MapSource> none = PlaceSubmapsPiecewise(Target(w, 0.02), whole, {});
  ASSERT_EQ(none.size(), 1u);
  EXPECT_EQ(none[0].map.size(), whole.map.size());
}

// A fit whose pairs disagree with the submap's shape (the target's trees there moved by half a
// metre each, in different directions) is refused, and the submap follows the chain.
TEST(PlaceSubmapsPiecewise, AFitThatDoesNotMatchTheSubmapsShapeIsRefused) {
  const World w(12, 2.0);
  std::mt19937_64 rng(6);
  const TrueChain t = Drive(w, Pose2{2.0, 2.0, 0.1}, 3, 3.0);
  const std::vector<WireSubmap> subs = BentChain(w, t, 0.0, rng);
  LandmarkMap target = Target(w, 0.02);
  std::set<int> first(t.seen[0].begin(), t.seen[0].end());
  for (int i : t.seen[1]) {
    if (first.contains(i)) continue;
    const double a = 2.4 * i;  // a direction per landmark
    target.landmarks[static_cast<std::size_t>(i)].mean += 0.5 * Eigen::Vector2d(std::cos(a), std::sin(a));
  }
  for (int i : t.seen[2]) first.insert(i);
  const MapSource whole{4, 1, {}, t.frames[0], 1e-4 * Eigen::Matrix3d::Identity(), false};
  PiecewiseStats stats;
  const std::vector<MapSource> placed = PlaceSubmapsPiecewise(target, whole, Pointers(subs), {}, &stats);
  ASSERT_EQ(placed.size(), 3u);
  EXPECT_GE(stats.refused, 1);
  EXPECT_EQ(stats.fitted + stats.chained, 3);
  EXPECT_EQ(stats.chained, stats.refused);
  // Submap 1 (refused) lies where submap 0's fit and its end pose put it: exact here.
  EXPECT_LT(PlacementError(placed[1].to_own, t.frames[1]), 1e-9);
}

// The fit's covariance bounds the placement's error whatever the target's landmarks share: over
// seeded noisy submaps (their end poses a few degrees off, so the chain puts some submaps on the
// wrong trees), the NEES of the placements of chains whose submaps all fitted stays within 3 on
// average, both when the target's errors are independent and when they are one error shared by
// all (a target map laid off as a whole), where independent errors would give NEES in the tens;
// the rest were refused by the gates, never placed by a wrong fit.
TEST(PlaceSubmapsPiecewise, FittedPlacementsAreConsistentWhateverTheTargetShares) {
  const World w(12, 2.0);
  const double sigma = 0.03;
  for (const bool shared : {false, true}) {
    std::mt19937_64 rng(7);
    std::normal_distribution<double> g;
    double nees = 0.0;
    int n = 0, all_fitted = 0;
    const int trials = 150;
    for (int trial = 0; trial < trials; ++trial) {
      const TrueChain t = Drive(w, Pose2{2.0 + 0.01 * trial, 2.0, 0.1}, 3, 3.0);
      const std::vector<WireSubmap> subs = MeasureAll(w, t, 4, rng);
      LandmarkMap target = Target(w, sigma);
      const Eigen::Vector2d common = sigma * Eigen::Vector2d(g(rng), g(rng));
      for (Landmark& l : target.landmarks) l.mean += shared ? common : sigma * Eigen::Vector2d(g(rng), g(rng));
      const MapSource whole{4, 1, {}, t.frames[0], 1e-4 * Eigen::Matrix3d::Identity(), false};
      PiecewiseStats stats;
      const std::vector<MapSource> placed = PlaceSubmapsPiecewise(target, whole, Pointers(subs), {}, &stats);
      EXPECT_EQ(stats.fitted + stats.refused, 3) << trial;  // a submap with too few pairs: none here
      if (stats.fitted < 3) continue;
      ++all_fitted;
      for (std::size_t k = 0; k < placed.size(); ++k) {
        Eigen::Vector3d e(placed[k].to_own.x - t.frames[k].x, placed[k].to_own.y - t.frames[k].y,
                          WrapAngle(placed[k].to_own.theta - t.frames[k].theta));
        const double d2 = e.dot(placed[k].to_own_cov.ldlt().solve(e));
        EXPECT_LT(d2, Chi2Quantile(0.9999, 3)) << trial << " " << k;  // no wrong fit
        nees += d2;
        ++n;
      }
    }
    EXPECT_GE(all_fitted, trials * 9 / 10) << shared;
    nees /= n;
    EXPECT_LT(nees, 3.0) << shared;
    EXPECT_GT(nees, 0.3) << shared;  // conservative, not vacuous
  }
}

}  // namespace
}  // namespace mapmesh
