#include "common/merge/submap_network.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "common/merge/chain_map.h"
#include "common/slam/submap_joiner.h"
#include "tests/testing/submap_world.h"

namespace mapmesh {
namespace {

using testing::Drive;
using testing::Measure;
using testing::MeasureAll;
using testing::TrueChain;
using testing::World;

// The chain input of a robot's submaps (incarnation 1), started at `origin`.
ChainInput Chain(RobotId robot, const std::vector<WireSubmap>& submaps, const Pose2& origin) {
  ChainInput c{robot, 1, {}, origin, {}, {}};
  for (const WireSubmap& s : submaps) c.submaps.push_back(&s);
  return c;
}

std::map<LandmarkRef, int> ByTruth(const std::vector<std::pair<RobotId, const TrueChain*>>& chains) {
  std::map<LandmarkRef, int> groups;
  for (const auto& [robot, c] : chains) {
    for (const auto& seen : c->seen) {
      for (int i : seen) groups[{robot, 1, static_cast<std::uint32_t>(i)}] = i;
    }
  }
  return groups;
}

// One chain alone is what the single-robot joiner gives: the same landmarks to 1e-6 m and the
// same covariances.
TEST(SubmapNetwork, OneChainIsTheSubmapJoiner) {
  const World w(8, 2.0);
  std::mt19937_64 rng(3);
  const TrueChain t = Drive(w, Pose2{1.0, 1.0, 0.1}, 4, 3.0);
  const std::vector<WireSubmap> subs = MeasureAll(w, t, 1, rng);
  JoinerOptions jo;
  jo.window = 100;
  SubmapJoiner joiner(jo);
  for (const WireSubmap& s : subs) joiner.Add(SubmapEstimate{s.x, s.Covariance(), s.keys});
  const ChainInput c = Chain(1, subs, Pose2{});
  const NetworkResult r = JoinSubmapNetwork(std::span<const ChainInput>(&c, 1), {});
  ASSERT_TRUE(r.solved);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.submaps, 4);
  const JoinedMap& j = joiner.last();
  int compared = 0;
  for (const NetworkLandmark& l : r.landmarks) {
    if (l.refs.empty()) continue;
    ASSERT_EQ(l.refs.size(), 1u);
    const auto i = j.Find(l.refs[0].key);
    ASSERT_TRUE(i.has_value());
    EXPECT_LT((l.mean - j.means[*i]).norm(), 1e-6);
    EXPECT_LT((l.cov - j.Cov(*i)).norm(), 1e-8 + 1e-5 * j.Cov(*i).norm());
    ++compared;
  }
  EXPECT_EQ(compared, static_cast<int>(j.keys.size()));
}

// Two robots that start far apart and drive towards each other, their landmarks grouped by the
// truth; the truth in the joined frame (a's first frame) and b's origin there.
struct TwoRobots {
  World w{10, 2.0};
  TrueChain a = Drive(w, Pose2{0.0, 4.0, 0.0}, 4, 3.5);
  TrueChain b = Drive(w, Pose2{18.0, 9.0, M_PI}, 4, 3.5);
  std::map<LandmarkRef, int> groups = ByTruth({{1, &a}, {2, &b}});
  Pose2 to_joined = a.frames[0].Inverse();
  Pose2 b_origin = to_joined * b.frames[0];
};

// The second robot placed 1.5 m and 8 degrees off: the join places it and is consistent over
// seeded draws (landmark NEES near 2, the second chain's origin within its sampling error), and
// more accurate than either chain alone where they overlap.
TEST(SubmapNetwork, TwoRobotsAreJoinedConsistently) {
  const TwoRobots t;
  const World& w = t.w;
  const TrueChain &a = t.a, &b = t.b;
  const std::map<LandmarkRef, int>& groups = t.groups;
  const Pose2 to_joined = t.to_joined, b_origin = t.b_origin;
  double nees = 0.0;
  int count = 0;
  double origin_err2 = 0.0;
  const int runs = 200;
  for (int run = 0; run < runs; ++run) {
    std::mt19937_64 rng(100 + run);
    const std::vector<WireSubmap> sa = MeasureAll(w, a, 1, rng), sb = MeasureAll(w, b, 2, rng);
    const std::vector<ChainInput> chains = {Chain(1, sa, Pose2{}), Chain(2, sb, b_origin * Pose2{1.5, -1.0, 0.14})};
    const NetworkResult r = JoinSubmapNetwork(chains, groups);
    ASSERT_TRUE(r.solved) << run;
    ASSERT_TRUE(r.joined[1]) << run;
    EXPECT_EQ(r.ties_dropped, 0) << run;
    for (std::size_t g = 0; g < w.landmarks.size(); ++g) {
      const NetworkLandmark* l = r.OfGroup(static_cast<int>(g));
      if (l == nullptr) continue;
      const Eigen::Vector2d e = l->mean - to_joined.Apply(w.landmarks[g]);
      nees += e.dot(l->cov.ldlt().solve(e));
      ++count;
    }
    const Pose2 d = b_origin.Inverse() * r.origins[1];
    origin_err2 += d.x * d.x + d.y * d.y;
  }
  nees /= count;
  EXPECT_GT(nees, 1.8);
  EXPECT_LT(nees, 2.2);
  EXPECT_LT(std::sqrt(origin_err2 / runs), 0.2);  // from 1.8 m off
}

// A chain's first submaps enter as their summary (ChainMap::Summary: the chain's own join of
// them, one submap from its first frame to the last one's end) and the join is the join of those
// submaps, to the linearisation within the chain: each chain's submaps are independent of every
// other's. Over seeded draws (heading errors of degrees, so the linearisation points differ by
// millimetres) the landmarks lie within a tenth of their own standard deviation of the join of
// every submap, their covariances within a percent, and the NEES stays near 2.
TEST(SubmapNetwork, AChainsFirstSubmapsSummarisedJoinAsThoseSubmaps) {
  const TwoRobots t;
  double nees = 0.0, worst_mean = 0.0, worst_cov = 0.0;  // worst_mean in standard deviations
  int count = 0;
  for (int run = 0; run < 50; ++run) {
    std::mt19937_64 rng(300 + run);
    const std::vector<WireSubmap> sa = MeasureAll(t.w, t.a, 1, rng), sb = MeasureAll(t.w, t.b, 2, rng);
    const Pose2 start = t.b_origin * Pose2{1.0, -0.5, 0.1};
    const std::vector<ChainInput> whole = {Chain(1, sa, Pose2{}), Chain(2, sb, start)};
    // Chain 1's first two submaps summarised, chain 2's first three.
    ChainMap ma, mb;
    const std::vector<const WireSubmap*> pa = {&sa[0], &sa[1]}, pb = {&sb[0], &sb[1], &sb[2]};
    ASSERT_EQ(ma.Extend(pa), 2u);
    ASSERT_EQ(mb.Extend(pb), 3u);
    const WireSubmap* summary_a = ma.Summary(sa[1]);
    const WireSubmap* summary_b = mb.Summary(sb[2]);
    ASSERT_NE(summary_a, nullptr);
    ASSERT_NE(summary_b, nullptr);
    EXPECT_EQ(summary_b->id.index, 2u | kSummaryIndexBit);
    EXPECT_EQ(ma.Summary(sa[1]), summary_a);  // kept until another submap is joined
    std::vector<ChainInput> summarised = {ChainInput{1, 1, {summary_a, &sa[2], &sa[3]}, Pose2{}, {}, {}},
                                          ChainInput{2, 1, {summary_b, &sb[3]}, start, {}, {}}};
    const NetworkResult r = JoinSubmapNetwork(whole, t.groups);
    const NetworkResult s = JoinSubmapNetwork(summarised, t.groups);
    ASSERT_TRUE(r.solved && s.solved) << run;
    ASSERT_TRUE(r.joined[1] && s.joined[1]) << run;
    EXPECT_EQ(s.frames[1].size(), 3u);  // X_0, X_3 (the summary's end), X_4
    EXPECT_LT((s.frames[1].back().Vector() - r.frames[1].back().Vector()).cwiseAbs().maxCoeff(), 1e-3) << run;
    for (std::size_t g = 0; g < t.w.landmarks.size(); ++g) {
      const NetworkLandmark* a = r.OfGroup(static_cast<int>(g));
      const NetworkLandmark* b = s.OfGroup(static_cast<int>(g));
      ASSERT_EQ(a == nullptr, b == nullptr) << run << " " << g;
      if (a == nullptr) continue;
      const Eigen::Vector2d d = a->mean - b->mean;
      worst_mean = std::max(worst_mean, std::sqrt(d.dot(a->cov.ldlt().solve(d))));
      worst_cov = std::max(worst_cov, ((a->cov - b->cov).norm() / a->cov.norm()));
      const Eigen::Vector2d e = b->mean - t.to_joined.Apply(t.w.landmarks[g]);
      nees += e.dot(b->cov.ldlt().solve(e));
      ++count;
    }
  }
  EXPECT_LT(worst_mean, 0.1);
  EXPECT_LT(worst_cov, 0.01);
  nees /= count;
  EXPECT_GT(nees, 1.7);
  EXPECT_LT(nees, 2.3);
}

// NetworkOptions::calibrate_sigmas: a chain whose submaps err twice as much as their covariance
// says (four times the variance) is found by its residuals against the other chain: its
// variance factor is several times the other's (near 4, a little below: the redundancy is
// approximate), its information weighs less, and the landmarks' NEES comes back to about 2
// (near 4 uncalibrated). Consistent chains are left alone in most draws (no extra solve).
TEST(SubmapNetwork, AChainThatErrsBeyondItsCovarianceIsCalibratedByItsResiduals) {
  const TwoRobots t;
  NetworkOptions calibrated;
  calibrated.calibrate_sigmas = 3.0;
  double nees_plain = 0.0, nees_calibrated = 0.0, factor_a = 0.0, factor_b = 0.0;
  int count = 0, runs = 0, consistent_calibrations = 0;
  for (int run = 0; run < 40; ++run) {
    std::mt19937_64 rng(500 + run);
    const std::vector<WireSubmap> sa = MeasureAll(t.w, t.a, 1, rng);
    std::vector<WireSubmap> sb = MeasureAll(t.w, t.b, 2, rng);
    for (std::size_t k = 0; k < sb.size(); ++k) {  // robot 2's errors doubled
      std::vector<Eigen::Vector2d> points;
      for (int i : t.b.seen[k]) points.push_back(t.w.landmarks[static_cast<std::size_t>(i)]);
      const Eigen::VectorXd h = PredictSubmap(t.b.frames[k], t.b.frames[k + 1], points);
      sb[k].x = h + 2.0 * (sb[k].x - h);
    }
    const Pose2 start = t.b_origin * Pose2{1.0, -0.5, 0.1};
    const std::vector<ChainInput> chains = {Chain(1, sa, Pose2{}), Chain(2, sb, start)};
    const NetworkResult plain = JoinSubmapNetwork(chains, t.groups);
    const NetworkResult r = JoinSubmapNetwork(chains, t.groups, calibrated);
    ASSERT_TRUE(plain.solved && r.solved) << run;
    ASSERT_TRUE(r.joined[1]) << run;
    ASSERT_EQ(r.variance_factors.size(), 2u);
    EXPECT_EQ(plain.calibrations, 0);
    factor_a += r.variance_factors[0];
    factor_b += r.variance_factors[1];
    ++runs;
    for (std::size_t g = 0; g < t.w.landmarks.size(); ++g) {
      const NetworkLandmark* a = plain.OfGroup(static_cast<int>(g));
      const NetworkLandmark* b = r.OfGroup(static_cast<int>(g));
      if (a == nullptr || b == nullptr) continue;
      const Eigen::Vector2d truth = t.to_joined.Apply(t.w.landmarks[g]);
      nees_plain += (a->mean - truth).dot(a->cov.ldlt().solve(a->mean - truth));
      nees_calibrated += (b->mean - truth).dot(b->cov.ldlt().solve(b->mean - truth));
      ++count;
    }
    // The same draw with robot 2 as its covariance says.
    const std::vector<WireSubmap> fair = MeasureAll(t.w, t.b, 2, rng);
    const std::vector<ChainInput> consistent = {Chain(1, sa, Pose2{}), Chain(2, fair, start)};
    consistent_calibrations += JoinSubmapNetwork(consistent, t.groups, calibrated).calibrations > 0 ? 1 : 0;
  }
  nees_plain /= count;
  nees_calibrated /= count;
  EXPECT_GT(nees_plain, 3.0);
  EXPECT_GT(nees_calibrated, 1.5);
  EXPECT_LT(nees_calibrated, 2.5);
  EXPECT_LT(factor_a / runs, 1.5);
  EXPECT_GT(factor_b / runs, 2.5);
  EXPECT_LE(consistent_calibrations, 4);  // at 3 sigmas, chance alone: a few in a hundred per chain
}

// A chain that errs as a whole (robot 2's errors three times its covariance: every submap far
// beyond its chi-square) refuses a join judged on the start frames by its residuals, and the
// first pass runs again at every join; with the calibration the check is made under the
// variance factors, and the join judged on the frames stands (the first pass could not mend it).
TEST(SubmapNetwork, AChainThatErrsAsAWholeDoesNotRunTheFirstPassAtEveryJoin) {
  const TwoRobots t;
  NetworkOptions calibrated;
  calibrated.calibrate_sigmas = 3.0;
  int rechecked_plain = 0, rechecked_calibrated = 0;
  for (int run = 0; run < 10; ++run) {
    std::mt19937_64 rng(900 + run);
    const std::vector<WireSubmap> sa = MeasureAll(t.w, t.a, 1, rng);
    std::vector<WireSubmap> sb = MeasureAll(t.w, t.b, 2, rng);
    for (std::size_t k = 0; k < sb.size(); ++k) {
      std::vector<Eigen::Vector2d> points;
      for (int i : t.b.seen[k]) points.push_back(t.w.landmarks[static_cast<std::size_t>(i)]);
      const Eigen::VectorXd h = PredictSubmap(t.b.frames[k], t.b.frames[k + 1], points);
      sb[k].x = h + 3.0 * (sb[k].x - h);
    }
    std::vector<ChainInput> chains = {Chain(1, sa, Pose2{}), Chain(2, sb, t.b_origin * Pose2{1.0, -0.5, 0.1})};
    for (const NetworkOptions& o : {NetworkOptions{}, calibrated}) {
      std::vector<ChainInput> judged = chains;
      const NetworkResult before = JoinSubmapNetwork(judged, t.groups, o);
      ASSERT_TRUE(before.solved && before.joined[1]) << run;
      for (std::size_t c = 0; c < judged.size(); ++c) judged[c].start_frames = before.frames[c];
      const NetworkResult r = JoinSubmapNetwork(judged, t.groups, o);
      ASSERT_TRUE(r.solved && r.joined[1]) << run;
      (o.calibrate_sigmas > 0 ? rechecked_calibrated : rechecked_plain) += r.rechecked ? 1 : 0;
      if (o.calibrate_sigmas > 0) {
        EXPECT_GT(r.variance_factors[1], 4.0) << run;
      }
    }
  }
  EXPECT_EQ(rechecked_plain, 10);
  EXPECT_EQ(rechecked_calibrated, 0);
}

// A chain whose origin is held stays exactly there, and the rest of the join moves to it: with the
// true origin held the second chain's landmarks are no further from the truth than when it is
// found (it knows more); a held origin off by 0.5 m pulls the join with it.
TEST(SubmapNetwork, AHeldOriginStaysWhereItIsGiven) {
  const TwoRobots t;
  const World& w = t.w;
  const std::map<LandmarkRef, int>& groups = t.groups;
  const Pose2 to_joined = t.to_joined, b_origin = t.b_origin;
  std::mt19937_64 rng(7);
  const std::vector<WireSubmap> sa = MeasureAll(w, t.a, 1, rng), sb = MeasureAll(w, t.b, 2, rng);
  auto error = [&](const NetworkResult& r) {
    double se = 0.0;
    int n = 0;
    for (std::size_t g = 0; g < w.landmarks.size(); ++g) {
      if (const NetworkLandmark* l = r.OfGroup(static_cast<int>(g))) {
        se += (l->mean - to_joined.Apply(w.landmarks[g])).squaredNorm();
        ++n;
      }
    }
    return std::sqrt(se / n);
  };
  const NetworkResult found = JoinSubmapNetwork(
      std::vector<ChainInput>{Chain(1, sa, Pose2{}), Chain(2, sb, b_origin * Pose2{1.5, -1.0, 0.14})}, groups);
  for (const Pose2& held : {b_origin, b_origin * Pose2{0.5, 0.0, 0.0}}) {
    std::vector<ChainInput> chains = {Chain(1, sa, Pose2{}), Chain(2, sb, held)};
    chains[1].origin_fixed = true;
    const NetworkResult r = JoinSubmapNetwork(chains, groups);
    ASSERT_TRUE(r.solved && r.converged && r.joined[1]);
    EXPECT_EQ(r.origins[1].x, held.x);
    EXPECT_EQ(r.origins[1].y, held.y);
    EXPECT_EQ(r.origins[1].theta, held.theta);
    EXPECT_EQ(r.frames[1][0].x, held.x);
    if (held.x == b_origin.x) {
      EXPECT_LE(error(r), error(found) * 1.05);
      EXPECT_LT(r.cost, found.cost + 20.0);
    } else {
      EXPECT_GT(r.cost, found.cost + 20.0);  // 0.5 m against the submaps' centimetres
    }
  }
}

// Wrong pairings (each of robot 2's landmarks paired with a neighbour of the true one, 2 m away,
// as a gate in a row of trees would) are dropped by the first pass, and the chain is placed and
// joined exactly as with the right association less those four pairings.
// Two robots driving a row of trees 2 m apart from its two ends, the second chain placed
// 0.5 m and 1 degree off; the right association, and a wrong one: four of robot 2's landmarks,
// each swapped with its neighbour 2 m away (as a gate in a row of trees would pair them), all
// seen by robot 1 too.
struct SwappedRow {
  World w{10, 2.0};
  TrueChain a = Drive(w, Pose2{0.0, 4.0, 0.0}, 4, 3.5);
  TrueChain b = Drive(w, Pose2{18.0, 9.0, M_PI}, 4, 3.5);
  std::vector<WireSubmap> sa, sb;
  std::vector<ChainInput> chains;
  std::map<LandmarkRef, int> right, wrong;
  std::map<LandmarkRef, int> right_less;  // the right one without the swapped landmarks' pairings
  std::set<int> in_a, swapped;

  SwappedRow() {
    right = ByTruth({{1, &a}, {2, &b}});
    std::set<int> in_b;
    for (const auto& seen : a.seen) in_a.insert(seen.begin(), seen.end());
    for (const auto& seen : b.seen) in_b.insert(seen.begin(), seen.end());
    wrong = right;
    for (int i : in_b) {
      if (swapped.size() == 4 || !in_a.count(i) || !in_a.count(i + 1) || (i + 1) % 10 == 0) continue;
      if (!in_b.count(i + 1) || swapped.count(i) || swapped.count(i + 1)) continue;
      std::swap(wrong[{2, 1, static_cast<std::uint32_t>(i)}], wrong[{2, 1, static_cast<std::uint32_t>(i + 1)}]);
      swapped.insert({i, i + 1});
    }
    right_less = right;
    for (int i : swapped) right_less.erase({2, 1, static_cast<std::uint32_t>(i)});
    std::mt19937_64 rng(5);
    sa = MeasureAll(w, a, 1, rng);
    sb = MeasureAll(w, b, 2, rng);
    const Pose2 b_origin = a.frames[0].Inverse() * b.frames[0];
    chains = {Chain(1, sa, Pose2{}), Chain(2, sb, b_origin * Pose2{0.4, -0.3, 0.02})};
  }
  // Every landmark robot 1 saw that no swap reaches is where `expected` puts it, to `tolerance`;
  // returns how many were compared.
  int ExpectUnswappedAsIn(const NetworkResult& expected, const NetworkResult& r, double tolerance) const {
    int compared = 0;
    for (int g : in_a) {
      if (swapped.count(g)) continue;
      EXPECT_NE(expected.OfGroup(g), nullptr);
      EXPECT_NE(r.OfGroup(g), nullptr);
      if (expected.OfGroup(g) == nullptr || r.OfGroup(g) == nullptr) continue;
      EXPECT_LT((expected.OfGroup(g)->mean - r.OfGroup(g)->mean).norm(), tolerance) << g;
      ++compared;
    }
    return compared;
  }
};

// Wrong pairings are dropped by the first pass, and the chain is placed and joined exactly as
// with the right association less those four pairings.
TEST(SubmapNetwork, WrongPairingsAreDroppedNotJoined) {
  const SwappedRow row;
  ASSERT_EQ(row.swapped.size(), 4u);
  const NetworkResult good = JoinSubmapNetwork(row.chains, row.right_less);
  const NetworkResult r = JoinSubmapNetwork(row.chains, row.wrong);
  ASSERT_TRUE(good.solved);
  ASSERT_TRUE(r.solved);
  EXPECT_TRUE(r.first_pass);  // no start frames: the first pass judges
  EXPECT_EQ(good.ties_dropped, 0);
  EXPECT_EQ(r.ties_dropped, 4);  // the planted ones (the true pairings they displaced were never offered)
  const Pose2 d = good.origins[1].Inverse() * r.origins[1];
  EXPECT_LT(std::hypot(d.x, d.y), 1e-6);
  // The landmarks the planted pairings do not reach are where the right join puts them.
  EXPECT_GT(row.ExpectUnswappedAsIn(good, r, 1e-6), 10);
}

// The chains started from a previous join's frames and landmarks: the pairings are judged on
// the frames, without the first pass, and the join is the first pass's to 10 micrometres (the
// two solves start from different states and each stops at a millionth of the cost:
// micrometres from the optimum). The wrong pairings lie 2 m apart on those frames and are dropped as the first pass
// drops them. Without the option, or when one chain lacks frames, the first pass runs.
TEST(SubmapNetwork, PairingsAreJudgedOnAPreviousJoinsFrames) {
  SwappedRow row;
  const NetworkResult before = JoinSubmapNetwork(row.chains, row.right);
  ASSERT_TRUE(before.solved);
  ASSERT_TRUE(before.joined[1]);
  const std::vector<ChainInput> unplaced = row.chains;
  for (std::size_t c = 0; c < row.chains.size(); ++c) row.chains[c].start_frames = before.frames[c];
  for (const NetworkLandmark& l : before.landmarks) {
    for (const LandmarkRef& ref : l.refs) row.chains[ref.robot - 1].start_landmarks[ref.key] = l.mean;
  }
  for (const auto* groups : {&row.right, &row.wrong}) {
    const NetworkResult first = JoinSubmapNetwork(unplaced, *groups);
    const NetworkResult r = JoinSubmapNetwork(row.chains, *groups);
    ASSERT_TRUE(first.solved);
    ASSERT_TRUE(r.solved);
    EXPECT_TRUE(first.first_pass);
    EXPECT_FALSE(r.first_pass);
    EXPECT_FALSE(r.rechecked);
    EXPECT_EQ(r.ties_dropped, first.ties_dropped);
    EXPECT_EQ(r.ties_dropped, groups == &row.wrong ? 4 : 0);
    EXPECT_GT(row.ExpectUnswappedAsIn(first, r, 1e-5), 10);
    for (std::size_t i = 0; i < r.landmarks.size(); ++i) {
      EXPECT_LT((r.landmarks[i].cov - first.landmarks[i].cov).norm(), 1e-9 + 1e-6 * first.landmarks[i].cov.norm());
    }
  }
  NetworkOptions every;
  every.judge_on_start_frames = false;
  EXPECT_TRUE(JoinSubmapNetwork(row.chains, row.wrong, every).first_pass);
  std::vector<ChainInput> one_unplaced = row.chains;
  one_unplaced[1].start_frames.clear();
  NetworkOptions not_alone;
  not_alone.place_new_chains_alone = false;
  EXPECT_TRUE(JoinSubmapNetwork(one_unplaced, row.wrong, not_alone).first_pass);
  EXPECT_EQ(JoinSubmapNetwork(one_unplaced, row.wrong, not_alone).placed_alone, 0);
}

// A chain new to the join (no start frames) while the first chain has them is placed alone
// against the first's frames, from its alignment's placement, and the pairings are judged on
// the frames: the four wrong pairings are dropped as the first pass drops them, and the join is
// the first pass's. So is it when the new chain's placement is 1 m and 0.1 rad off (the ties'
// Cauchy kernel lets go of the wrong pairings, the weak origin prior does not hold it there).
TEST(SubmapNetwork, AChainNewToTheJoinIsPlacedAloneAgainstTheOthersFrames) {
  SwappedRow row;
  const NetworkResult before = JoinSubmapNetwork(row.chains, row.right);
  ASSERT_TRUE(before.solved);
  const NetworkResult expected = JoinSubmapNetwork(row.chains, row.wrong);  // the first pass
  ASSERT_TRUE(expected.first_pass);
  row.chains[0].start_frames = before.frames[0];
  for (const Pose2& off : {Pose2{}, Pose2{1.0, -0.5, 0.1}}) {
    std::vector<ChainInput> chains = row.chains;
    chains[1].origin = chains[1].origin * off;
    const NetworkResult r = JoinSubmapNetwork(chains, row.wrong);
    ASSERT_TRUE(r.solved);
    EXPECT_EQ(r.placed_alone, 1);
    EXPECT_FALSE(r.first_pass);
    EXPECT_FALSE(r.rechecked);
    EXPECT_TRUE(r.joined[1]);
    EXPECT_EQ(r.ties_dropped, 4);
    EXPECT_GT(row.ExpectUnswappedAsIn(expected, r, 1e-5), 10);
  }
}

// A join judged on the start frames whose residuals exceed the check is run again with the
// first pass: the same join, to the bit, as one that runs the first pass from the start.
TEST(SubmapNetwork, AJoinItsResidualsRefuseRunsTheFirstPass) {
  SwappedRow row;
  const NetworkResult before = JoinSubmapNetwork(row.chains, row.right);
  ASSERT_TRUE(before.solved);
  for (std::size_t c = 0; c < row.chains.size(); ++c) row.chains[c].start_frames = before.frames[c];
  NetworkOptions refuse;
  refuse.recheck_sigmas = -1e9;  // every residual is too large
  NetworkOptions first_pass;
  first_pass.judge_on_start_frames = false;
  const NetworkResult r = JoinSubmapNetwork(row.chains, row.wrong, refuse);
  const NetworkResult expected = JoinSubmapNetwork(row.chains, row.wrong, first_pass);
  ASSERT_TRUE(r.solved);
  EXPECT_TRUE(r.first_pass);
  EXPECT_TRUE(r.rechecked);
  EXPECT_FALSE(expected.rechecked);
  ASSERT_EQ(r.landmarks.size(), expected.landmarks.size());
  for (std::size_t i = 0; i < r.landmarks.size(); ++i) {
    EXPECT_EQ(r.landmarks[i].mean, expected.landmarks[i].mean);
    EXPECT_EQ(r.landmarks[i].cov, expected.landmarks[i].cov);
  }
  EXPECT_EQ(r.ties_dropped, expected.ties_dropped);
  // With the default check these consistent submaps pass.
  EXPECT_FALSE(JoinSubmapNetwork(row.chains, row.wrong).rechecked);
}

// A submap whose errors lie far beyond its covariance (robot 2's second, three times its
// errors: a sensor's fault, not a pairing's) refuses a join judged on the start frames, and the
// recheck's first pass keeps the same pairings: the memo learns that excess as the submap's own,
// and the next join on the same frames is not rechecked (the same join), while one without the
// memo is. Should the submap's excess grow past what was learnt by the check's margin (its
// errors five times), the join is rechecked again.
TEST(SubmapNetwork, AnExcessARecheckFoundASubmapsOwnIsNotRecheckedAgain) {
  SwappedRow row;
  const auto erring = [&](double scale) {
    std::vector<WireSubmap> sb = row.sb;
    std::vector<Eigen::Vector2d> points;
    for (int i : row.b.seen[1]) points.push_back(row.w.landmarks[static_cast<std::size_t>(i)]);
    const Eigen::VectorXd h = PredictSubmap(row.b.frames[1], row.b.frames[2], points);
    sb[1].x = h + scale * (sb[1].x - h);
    return sb;
  };
  const std::vector<WireSubmap> three = erring(3.0), five = erring(5.0);
  std::vector<ChainInput> chains = {row.chains[0], Chain(2, three, row.chains[1].origin)};
  const NetworkResult before = JoinSubmapNetwork(chains, row.right);
  ASSERT_TRUE(before.solved && before.joined[1]);
  for (std::size_t c = 0; c < chains.size(); ++c) chains[c].start_frames = before.frames[c];
  RecheckMemo memo;
  const NetworkResult learnt = JoinSubmapNetwork(chains, row.right, {}, nullptr, &memo);
  ASSERT_TRUE(learnt.solved);
  EXPECT_TRUE(learnt.rechecked);
  EXPECT_TRUE(learnt.recheck_unchanged);
  EXPECT_FALSE(learnt.recheck_spared);
  EXPECT_EQ(memo.Cleared(SubmapId{2, 1, 1}) > 10.0, true);
  EXPECT_EQ(memo.Cleared(SubmapId{1, 1, 0}), -std::numeric_limits<double>::infinity());

  const NetworkResult spared = JoinSubmapNetwork(chains, row.right, {}, nullptr, &memo);
  ASSERT_TRUE(spared.solved);
  EXPECT_FALSE(spared.rechecked);
  EXPECT_FALSE(spared.first_pass);
  EXPECT_TRUE(spared.recheck_spared);
  EXPECT_EQ(spared.ties_dropped, learnt.ties_dropped);
  ASSERT_EQ(spared.landmarks.size(), learnt.landmarks.size());
  for (std::size_t i = 0; i < spared.landmarks.size(); ++i) {
    EXPECT_LT((spared.landmarks[i].mean - learnt.landmarks[i].mean).norm(), 1e-5) << i;
  }
  EXPECT_TRUE(JoinSubmapNetwork(chains, row.right).rechecked);  // without the memo

  std::vector<ChainInput> worse = {chains[0], Chain(2, five, chains[1].origin)};
  worse[1].start_frames = chains[1].start_frames;
  RecheckMemo kept = memo;
  EXPECT_TRUE(JoinSubmapNetwork(worse, row.right, {}, nullptr, &kept).rechecked);
  // A join that no longer takes a submap forgets what was learnt of it.
  std::vector<ChainInput> alone = {chains[0]};
  JoinSubmapNetwork(alone, row.right, {}, nullptr, &memo);
  EXPECT_EQ(memo.size(), 0u);
}

// A chain that shares too few landmarks with those in is left out (and its landmarks with it);
// one that shares them only with a chain placed after it enters through that chain.
TEST(SubmapNetwork, AChainEntersOnlyThroughSharedLandmarks) {
  const World w(14, 2.0);
  std::mt19937_64 rng(7);
  const TrueChain a = Drive(w, Pose2{0.0, 2.0, 0.0}, 2, 3.0);
  const TrueChain far = Drive(w, Pose2{0.0, 18.0, 0.0}, 2, 3.0);    // never near a
  const TrueChain bridge = Drive(w, Pose2{4.0, 2.0, 1.2}, 4, 3.5);  // from a's ground up to far's
  const std::vector<WireSubmap> sa = MeasureAll(w, a, 1, rng), sf = MeasureAll(w, far, 2, rng),
                                sb = MeasureAll(w, bridge, 3, rng);
  const Pose2 to_joined = a.frames[0].Inverse();
  const std::vector<ChainInput> chains = {Chain(1, sa, Pose2{}), Chain(2, sf, to_joined * far.frames[0]),
                                          Chain(3, sb, to_joined * bridge.frames[0])};
  const std::map<LandmarkRef, int> groups = ByTruth({{1, &a}, {2, &far}, {3, &bridge}});
  // Without the bridge, the far chain shares nothing with a.
  const NetworkResult alone = JoinSubmapNetwork(std::span<const ChainInput>(chains.data(), 2), groups);
  ASSERT_TRUE(alone.solved);
  EXPECT_FALSE(alone.joined[1]);
  for (const NetworkLandmark& l : alone.landmarks) {
    for (const LandmarkRef& ref : l.refs) EXPECT_EQ(ref.robot, 1u);
  }
  const NetworkResult all = JoinSubmapNetwork(chains, groups);
  ASSERT_TRUE(all.solved);
  EXPECT_TRUE(all.joined[1]);
  EXPECT_TRUE(all.joined[2]);
  const Pose2 d = (to_joined * far.frames[0]).Inverse() * all.origins[1];
  EXPECT_LT(std::hypot(d.x, d.y), 0.5);
}

// An association that puts two of one submap's landmarks into one group is split there rather
// than joined (a landmark cannot be two of one submap's), and nothing throws.
TEST(SubmapNetwork, AGroupOneSubmapWouldReachTwiceIsSplit) {
  const World w(6, 2.0);
  std::mt19937_64 rng(11);
  const TrueChain a = Drive(w, Pose2{1.0, 3.0, 0.0}, 2, 3.0);
  const std::vector<WireSubmap> sa = MeasureAll(w, a, 1, rng);
  std::map<LandmarkRef, int> groups = ByTruth({{1, &a}});
  const std::uint32_t k0 = sa[0].keys[0], k1 = sa[0].keys[1];
  groups[{1, 1, k1}] = groups[{1, 1, k0}];
  ChainInput c{1, 1, {&sa[0], &sa[1]}, Pose2{}, {}, {}};
  const NetworkResult r = JoinSubmapNetwork(std::span<const ChainInput>(&c, 1), groups);
  ASSERT_TRUE(r.solved);
  int holding_k0 = 0, holding_k1 = 0;
  for (const NetworkLandmark& l : r.landmarks) {
    for (const LandmarkRef& ref : l.refs) {
      holding_k0 += ref.key == k0;
      holding_k1 += ref.key == k1;
    }
    EXPECT_LE(l.refs.size(), 1u);
  }
  EXPECT_EQ(holding_k0, 1);
  EXPECT_EQ(holding_k1, 1);
}

// The information matrices kept from one join to the next give the same join, to the bit; a
// submap's is computed once while its covariance stays, afresh when it changes (an open submap
// under one identity), and dropped once a join no longer uses it.
TEST(SubmapNetwork, KeptInformationGivesTheSameJoin) {
  const World w(10, 2.0);
  std::mt19937_64 rng(5);
  const TrueChain ta = Drive(w, Pose2{1.0, 1.0, 0.1}, 4, 3.0), tb = Drive(w, Pose2{2.0, 6.0, -0.1}, 3, 3.0);
  std::vector<WireSubmap> sa = MeasureAll(w, ta, 1, rng), sb = MeasureAll(w, tb, 2, rng);
  const std::vector<ChainInput> chains = {Chain(1, sa, Pose2{}), Chain(2, sb, Pose2{1.0, 5.0, -0.2})};
  const std::map<LandmarkRef, int> groups = ByTruth({{1, &ta}, {2, &tb}});
  SubmapInformation kept;
  const NetworkResult fresh = JoinSubmapNetwork(chains, groups);
  const NetworkResult first = JoinSubmapNetwork(chains, groups, {}, &kept);
  EXPECT_EQ(kept.computed(), 7);
  const NetworkResult again = JoinSubmapNetwork(chains, groups, {}, &kept);
  EXPECT_EQ(kept.computed(), 7);  // nothing changed: nothing computed
  for (const NetworkResult* r : {&first, &again}) {
    ASSERT_TRUE(r->solved);
    ASSERT_EQ(r->landmarks.size(), fresh.landmarks.size());
    for (std::size_t i = 0; i < fresh.landmarks.size(); ++i) {
      EXPECT_EQ(r->landmarks[i].mean, fresh.landmarks[i].mean);
      EXPECT_EQ(r->landmarks[i].cov, fresh.landmarks[i].cov);
    }
  }
  // Robot 2's last submap changes under its identity (as an open one does): computed afresh, and
  // the join is the one of the changed submap.
  sb.back() = Measure(w, tb, 2, 2, rng);
  const NetworkResult changed = JoinSubmapNetwork(chains, groups, {}, &kept);
  EXPECT_EQ(kept.computed(), 8);
  const NetworkResult changed_fresh = JoinSubmapNetwork(chains, groups);
  ASSERT_EQ(changed.landmarks.size(), changed_fresh.landmarks.size());
  for (std::size_t i = 0; i < changed.landmarks.size(); ++i) {
    EXPECT_EQ(changed.landmarks[i].mean, changed_fresh.landmarks[i].mean);
  }
  // Robot 1 alone: robot 2's entries go.
  JoinSubmapNetwork(std::span<const ChainInput>(chains).first(1), groups, {}, &kept);
  EXPECT_EQ(kept.size(), 4u);
}

}  // namespace
}  // namespace mapmesh
