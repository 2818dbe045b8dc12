#include "agent/fusion_backend.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>
#include <set>

#include "common/merge/chain_map.h"
#include "tests/testing/submap_world.h"

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
  return MapSource{robot, 1, map, to_own, 1e-8 * Eigen::Matrix3d::Identity(), false};
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
  ExchangeOptions o;
  o.global.method = FusionMethod::kCiConstant;
  const auto ci = MakeFusionBackend(1, 1, o, 1);
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

// Given the submaps it holds (agent.ci_placement piecewise), CI places a peer's submap on its own
// against our map: laid 0.03 rad off by its alignment, robot 2's map would put the landmarks only
// it saw (6-8) up to 0.6 m off; its submap, fitted on the three we share, puts them within the
// maps' noise. A relayed global map still enters whole.
TEST_F(FusionBackendTest, CovarianceIntersectionPlacesAPeersSubmapsOnTheirOwn) {
  ExchangeOptions o;
  o.global.method = FusionMethod::kCiConstant;
  SubmapBook book;
  const WireSubmap theirs = ExactSubmap(2, 0, 3, 9, frame2);  // landmarks 3-8 (their ids 0-5)
  book.Add(theirs, EncodeSubmap(theirs));
  const Pose2 off = Pose2{0.0, 0.0, 0.03} * frame2;
  const std::vector<MapSource> sources = {Source(2, two, off)};
  const FusionBackend::Built rigid = MakeFusionBackend(1, 1, o, 1)->Build(own, sources, sources);
  const FusionBackend::Built piecewise = MakeFusionBackend(1, 1, o, 1)
                                             ->Build(own, sources, sources, SubmapInputs{.book = &book});
  EXPECT_EQ(piecewise.piecewise.fitted, 1);  // once for the global map and the published one
  EXPECT_EQ(piecewise.piecewise.chained, 0);
  EXPECT_EQ(rigid.piecewise.submaps, 0);
  ASSERT_EQ(piecewise.global.map.size(), 9u);  // 0-8, each once
  EXPECT_GT(rigid.global.map.size(), 9u);      // laid off, shared landmarks fail the gate: duplicates
  // The worst landmark of robot 2's (anchored at one of its landmarks or fused with one).
  const auto worst = [](const GlobalMap& g) {
    double w = 0.0;
    for (std::size_t k = 0; k < g.map.size(); ++k) {
      for (const LandmarkOrigin& o : g.origins[k]) {
        if (o.robot != 2) continue;
        const int i = static_cast<int>(o.id) + 3;
        const Eigen::Vector2d truth(3.0 * i, (i % 3) * 4.0 + (i % 2) * 1.5);
        w = std::max(w, (g.map.landmarks[k].mean - truth).norm());
      }
    }
    return w;
  };
  const double worst_rigid = worst(rigid.global), worst_piecewise = worst(piecewise.global);
  EXPECT_GT(worst_rigid, 0.5);
  EXPECT_LT(worst_piecewise, 4 * kSigma);
  // A relay (a peer's global map) is not a chain: it enters as it is.
  MapSource relay = Source(2, two, off);
  relay.relayed = true;
  const FusionBackend::Built relayed = MakeFusionBackend(1, 1, o, 1)
                                           ->Build(own, {relay}, {}, SubmapInputs{.book = &book});
  EXPECT_EQ(relayed.piecewise.submaps, 0);
  const GlobalMap whole = BuildGlobalMap(own, 1, std::vector<MapSource>{relay}, o.global, 1);
  ASSERT_EQ(relayed.global.map.size(), whole.map.size());
  for (std::size_t g = 0; g < whole.map.size(); ++g)
    EXPECT_EQ(relayed.global.map.landmarks[g].mean, whole.map.landmarks[g].mean);
}

// With submap chains (cekf_submaps), joining takes every landmark a chain holds from the joint
// estimate of the chains (here exact measurements: the truth, whatever the noisy maps say), and
// a landmark no chain holds (robot 2's last, mapped after its submap) from the CI build.
TEST_F(FusionBackendTest, JoiningOnSubmapChainsTakesTheChainsEstimates) {
  ExchangeOptions o;
  o.global.method = FusionMethod::kJoining;
  SubmapBook book;
  const WireSubmap theirs = ExactSubmap(2, 0, 3, 8, frame2);  // landmarks 3-7 (their ids 0-4), not 8
  book.Add(theirs, EncodeSubmap(theirs));
  const WireSubmap ours = ExactSubmap(1, 0, 0, 6, Pose2{});
  SubmapInputs inputs{&book, &ours, nullptr};
  const FusionBackend::Built b = MakeFusionBackend(1, 1, o, 1)
                                     ->Build(own, {Source(2, two, frame2)}, {Source(2, two, frame2)}, inputs);
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
  EXPECT_EQ(b.joining.sources_by_ci, 0);
  // A third robot's aligned map, of which no submap is held, is the CI build's to fuse.
  const std::vector<MapSource> with_three = {Source(2, two, frame2), Source(3, two, frame2)};
  const FusionBackend::Built three = MakeFusionBackend(1, 1, o, 1)->Build(own, with_three, with_three, inputs);
  EXPECT_TRUE(three.joining.solved);
  EXPECT_EQ(three.joining.chains_joined, 2);
  EXPECT_EQ(three.joining.sources_by_ci, 1);
  // Without submaps the same back-end joins the maps (noisy: not the truth).
  const FusionBackend::Built maps = MakeFusionBackend(1, 1, o, 1)
                                        ->Build(own, {Source(2, two, frame2)}, {Source(2, two, frame2)});
  EXPECT_FALSE(maps.joining.solved);
  EXPECT_GT((Fused(maps.global, 4).mean - Eigen::Vector2d(12.0, 4.0)).norm(), 1e-3);
}

// agent.join_network_window: each chain's closed submaps but the last `window` enter the join as
// one summary (their chain's own join), and the join is the same: noise-free chains give the
// world exactly either way, with every submap counted once, also when a later build's summary
// stands for more submaps than the last one's (the frames it started from are renumbered).
TEST_F(FusionBackendTest, JoiningWithANetworkWindowSummarisesOldSubmapsToTheSameMap) {
  const Pose2 step{1.0, 0.5, 0.1};  // ExactSubmap's end pose
  std::vector<WireSubmap> closed;
  Pose2 ours_at, theirs_at = frame2;
  for (std::uint32_t k = 0; k < 4; ++k) {
    closed.push_back(ExactSubmap(1, k, 0, 6, ours_at));
    closed.push_back(ExactSubmap(2, k, 3, 9, theirs_at));
    ours_at = ours_at * step;
    theirs_at = theirs_at * step;
  }
  const std::vector<MapSource> sources = {Source(2, two, frame2)};
  for (int window : {limits::kMaxJoinNetworkWindow, 1, 0}) {
    ExchangeOptions o;
    o.global.method = FusionMethod::kJoining;
    o.network_window = window;
    const std::unique_ptr<FusionBackend> backend = MakeFusionBackend(1, 1, o, 1);
    SubmapBook book;
    for (std::size_t i = 0; i < 4; ++i) book.Add(closed[i], EncodeSubmap(closed[i]));  // two of each chain
    const WireSubmap first_open = closed[4];                                           // our submap 2, still open
    ASSERT_TRUE(backend->Build(own, sources, sources, SubmapInputs{&book, &first_open, nullptr}).joining.solved);
    for (std::size_t i = 4; i < 6; ++i) book.Add(closed[i], EncodeSubmap(closed[i]));
    const WireSubmap& open = closed[6];  // our submap 3
    const FusionBackend::Built b = backend->Build(own, sources, sources, SubmapInputs{&book, &open, nullptr});
    ASSERT_TRUE(b.joining.solved) << window;
    EXPECT_EQ(b.joining.chains_joined, 2) << window;
    EXPECT_EQ(b.joining.submaps, 7) << window;
    EXPECT_EQ(b.joining.ties_dropped, 0) << window;  // judged on the frames the last build solved
    EXPECT_EQ(b.joining.first_passes, 1) << window;  // the first build's only
    EXPECT_EQ(b.joining.iterations, 1) << window;    // started at the solution: its frames renumbered right
    EXPECT_EQ(b.joining.submaps_summarised, window == 0 ? 6 : window == 1 ? 4 : 0) << window;
    ASSERT_EQ(b.global.map.size(), 9u) << window;
    for (std::size_t g = 0; g < b.global.map.size(); ++g) {
      const LandmarkOrigin& first = b.global.origins[g].front();
      const int i = first.robot == 1 ? static_cast<int>(first.id) : static_cast<int>(first.id) + 3;
      const Eigen::Vector2d truth(3.0 * i, (i % 3) * 4.0 + (i % 2) * 1.5);
      EXPECT_LT((b.global.map.landmarks[g].mean - truth).norm(), 1e-6) << "window " << window << ", landmark " << i;
    }
  }
}

// Robot 2's map puts its landmark 8 where our landmark 2 is (a wrong pairing the association
// cannot tell), while its submap has it where it is. The join drops the pairing the submaps
// contradict, and both landmarks stay in the map: each where it is, its origins those the join
// merged (so no global landmark names two trees).
TEST_F(FusionBackendTest, JoiningKeepsBothLandmarksOfAPairingTheSubmapsContradict) {
  ExchangeOptions o;
  o.global.method = FusionMethod::kJoining;
  SubmapBook book;
  const WireSubmap theirs = ExactSubmap(2, 0, 3, 9, frame2);  // landmarks 3-8 (their ids 0-5)
  book.Add(theirs, EncodeSubmap(theirs));
  const WireSubmap ours = ExactSubmap(1, 0, 0, 6, Pose2{});
  LandmarkMap lying = two;
  lying.landmarks[5].mean = frame2.Inverse().Apply(own.landmarks[2].mean);  // "8" where our 2 is
  const std::vector<MapSource> sources = {Source(2, lying, frame2)};
  const FusionBackend::Built b = MakeFusionBackend(1, 1, o, 1)->Build(own, sources, sources, {&book, &ours, nullptr});
  ASSERT_TRUE(b.joining.solved);
  EXPECT_GE(b.joining.ties_dropped, 1);
  ASSERT_EQ(b.global.map.size(), 9u);  // 0-8, each once
  std::set<int> trees;
  for (std::size_t g = 0; g < b.global.map.size(); ++g) {
    std::set<int> named;
    for (const LandmarkOrigin& x : b.global.origins[g]) named.insert(x.robot == 1 ? int(x.id) : int(x.id) + 3);
    ASSERT_EQ(named.size(), 1u) << "global landmark " << g << " names trees " << ::testing::PrintToString(named);
    const int i = *named.begin();
    trees.insert(i);
    const Eigen::Vector2d truth(3.0 * i, (i % 3) * 4.0 + (i % 2) * 1.5);
    EXPECT_LT((b.global.map.landmarks[g].mean - truth).norm(), 1e-6) << "tree " << i;
  }
  EXPECT_EQ(trees.size(), 9u);
}

// A restarted robot whose new incarnation maps the time of its earlier one again (a lockstep
// restart replays its stream) has its earlier chain left out: the same measurements twice would
// be joined as independent. An incarnation that begins after the earlier one ended adds to it.
TEST_F(FusionBackendTest, JoiningLeavesOutAChainALaterIncarnationMapsAgain) {
  ExchangeOptions o;
  o.global.method = FusionMethod::kJoining;
  const auto submap = [&](std::uint32_t incarnation, double from) {
    WireSubmap s = ExactSubmap(2, 0, 3, 8, frame2);
    s.id.incarnation = incarnation;
    s.opened_s = from;
    s.closed_s = from + 10.0;
    return s;
  };
  const WireSubmap ours = ExactSubmap(1, 0, 0, 6, Pose2{});
  const auto build = [&](double second_from, bool first_held = true) {
    SubmapBook book;
    if (first_held) book.Add(submap(1, 0.0), EncodeSubmap(submap(1, 0.0)));
    book.Add(submap(2, second_from), EncodeSubmap(submap(2, second_from)));
    const std::vector<MapSource> sources = {MapSource{2, 1, two, frame2, 1e-8 * Eigen::Matrix3d::Identity(), false},
                                            MapSource{2, 2, two, frame2, 1e-8 * Eigen::Matrix3d::Identity(), false}};
    return MakeFusionBackend(1, 1, o, 1)->Build(own, sources, sources, SubmapInputs{&book, &ours, nullptr});
  };
  const FusionBackend::Built replayed = build(0.0);
  EXPECT_TRUE(replayed.joining.solved);
  EXPECT_EQ(replayed.joining.superseded_chains, 1);
  EXPECT_EQ(replayed.joining.chains, 2);  // own and 2.2
  EXPECT_EQ(replayed.joining.submaps, 2);
  // Landmark 7, which only robot 2 maps: as if 2.1's chain were not held; counted twice its
  // variance would be about half.
  const auto variance_of_7 = [](const GlobalMap& g) {
    for (std::size_t i = 0; i < g.origins.size(); ++i) {
      for (const LandmarkOrigin& e : g.origins[i]) {
        if (e.robot == 2 && e.id == 4) return g.map.landmarks[i].cov(0, 0);
      }
    }
    ADD_FAILURE() << "no global landmark of robot 2's landmark 4";
    return 0.0;
  };
  const double once = variance_of_7(replayed.global);
  EXPECT_EQ(once, variance_of_7(build(0.0, /*first_held=*/false).global));
  const FusionBackend::Built later = build(20.0);
  EXPECT_EQ(later.joining.superseded_chains, 0);
  EXPECT_EQ(later.joining.chains, 3);
  EXPECT_EQ(later.joining.submaps, 3);
  EXPECT_LT(variance_of_7(later.global), 0.75 * once);
}

TEST_F(FusionBackendTest, JoiningCountsEachRobotsInformationOnce) {
  ExchangeOptions o;
  o.global.method = FusionMethod::kJoining;
  const auto joining = MakeFusionBackend(1, 1, o, 1);
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
  ExchangeOptions o;
  o.global.method = FusionMethod::kCiConstant;
  const auto ci = MakeFusionBackend(1, 1, o, 1);
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
  o.global.method = FusionMethod::kJoining;
  const FusionBackend::Built j = MakeFusionBackend(1, 1, o, 1)
                                     ->Build(own, {Source(2, relay, frame2)}, {Source(2, two, frame2)});
  EXPECT_EQ(j.global.map.size(), 9u);
  EXPECT_EQ(j.published.map.size(), 9u);
}

// Three robots along a row of landmarks (J1, two hops): robot 3 never reached us (robot 1), but
// its submaps did, relayed by robot 2, whose map we hold aligned.
class FusionBackendRelayed : public ::testing::Test {
 protected:
  static testing::World Jittered() {
    testing::World w(20, 2.0);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> jitter(-0.6, 0.6);
    for (Eigen::Vector2d& l : w.landmarks) l += Eigen::Vector2d(jitter(rng), jitter(rng));
    return w;
  }
  static LandmarkMap Rebuilt(const std::vector<WireSubmap>& s) {
    std::vector<const WireSubmap*> p;
    for (const WireSubmap& x : s) p.push_back(&x);
    ChainMap c;
    c.Extend(p);
    return c.map();
  }
  static bool HoldsRobot3(const FusionBackend::Built& b) {
    for (const auto& origins : b.global.origins) {
      for (const LandmarkOrigin& g : origins) {
        if (g.robot == 3) return true;
      }
    }
    return false;
  }
  // A book of robots 1's and 2's submaps and robot 3's first `three`.
  SubmapBook Book(std::size_t three) const {
    SubmapBook book;
    for (const auto* s : {&s1, &s2}) {
      for (const WireSubmap& x : *s) book.Add(x, EncodeSubmap(x));
    }
    for (std::size_t k = 0; k < three; ++k) book.Add(s3[k], EncodeSubmap(s3[k]));
    return book;
  }
  // Our (robot 1's) first build holding `three` of robot 3's submaps (two: its rebuilt map
  // alone would need two alignments), with the peers' placements `offered` and the open
  // submaps `open`.
  FusionBackend::Built BuildOffered(const std::map<PeerKey, std::vector<ChainPlacement>>& offered,
                                    const std::map<PeerKey, WireSubmap>* open = nullptr, std::size_t three = 2) const {
    SubmapBook book = Book(three);
    return MakeFusionBackend(1, 1, o, 42)
        ->Build(own, direct, direct, {.book = &book, .peers_open = open, .now = 0.0, .peers_placements = &offered});
  }
  // Robot 2's join of its chain and robot 3's, whose placements it publishes.
  FusionBackend::Built BuildRobot2() const {
    SubmapBook book2;
    for (const auto* s : {&s2, &s3}) {
      for (const WireSubmap& x : *s) book2.Add(x, EncodeSubmap(x));
    }
    const std::vector<MapSource> heard2 = {
        {3, 1, Rebuilt(s3), start2.Inverse() * start3, 1e-6 * Eigen::Matrix3d::Identity()}};
    return MakeFusionBackend(2, 1, o, 42)->Build(Rebuilt(s2), heard2, heard2, {&book2, nullptr, nullptr, 0.0});
  }
  // Robot 3's landmarks in our global map: how many, and the largest NEES of one against the truth.
  std::pair<int, double> Robot3Landmarks(const FusionBackend::Built& b) const {
    int n = 0;
    double worst = 0.0;
    for (std::size_t g = 0; g < b.global.map.size(); ++g) {
      const auto& origins = b.global.origins[g];
      if (std::none_of(origins.begin(), origins.end(), [](const LandmarkOrigin& o) { return o.robot == 3; })) continue;
      const Eigen::Vector2d truth = start1.TransformTo(w.landmarks[origins.front().id]);  // keys are the world's
      const Landmark& l = b.global.map.landmarks[g];
      worst = std::max(worst, (l.mean - truth).dot(l.cov.ldlt().solve(l.mean - truth)));
      ++n;
    }
    return {n, worst};
  }

  testing::World w = Jittered();
  std::mt19937_64 rng{7};
  const Pose2 start1{1.0, 5.0, 0.0}, start2{13.0, 5.0, -0.2}, start3{25.0, 6.0, 0.1};
  const testing::TrueChain t1 = testing::Drive(w, start1, 4, 3.0);
  const testing::TrueChain t2 = testing::Drive(w, start2, 4, 3.0);
  const testing::TrueChain t3 = testing::Drive(w, start3, 4, 3.0);
  const std::vector<WireSubmap> s1 = testing::MeasureAll(w, t1, 1, rng);
  const std::vector<WireSubmap> s2 = testing::MeasureAll(w, t2, 2, rng);
  const std::vector<WireSubmap> s3 = testing::MeasureAll(w, t3, 3, rng);
  const LandmarkMap own = Rebuilt(s1);
  const std::vector<MapSource> direct = {
      {2, 1, Rebuilt(s2), start1.Inverse() * start2, 1e-6 * Eigen::Matrix3d::Identity()}};
  const ExchangeOptions o = [] {
    ExchangeOptions x;
    x.global.method = FusionMethod::kJoining;
    return x;
  }();
};

// The joining back-end rebuilds robot 3's map from its chain, aligns it against ours and robot
// 2's, and joins it once a later alignment (after the chain grew) agrees with the first: then
// robot 3's landmarks are in our global map where they are, and every chain is joined.
TEST_F(FusionBackendRelayed, AChainHeldOnlyThroughRelaysIsPlacedOnceConfirmedAndJoined) {
  // Robot 3's first `first` submaps at 0 s, then its first `then` at then_s.
  auto run = [&](std::size_t first, std::size_t then, double then_s) {
    SubmapBook book = Book(first);
    const auto backend = MakeFusionBackend(1, 1, o, 42);
    const FusionBackend::Built b = backend->Build(own, direct, direct, {&book, nullptr, nullptr, 0.0});
    EXPECT_EQ(b.joining.relayed_chains, 1);
    EXPECT_EQ(b.joining.relayed_alignments, 1);
    EXPECT_EQ(b.joining.relayed_placed, 0);  // one alignment is not enough
    for (std::size_t k = first; k < then; ++k) book.Add(s3[k], EncodeSubmap(s3[k]));
    return backend->Build(own, direct, direct, {&book, nullptr, nullptr, then_s});
  };
  // Nothing grew and the align period has not passed: no second alignment yet.
  const FusionBackend::Built early = run(2, 2, 1.0);
  EXPECT_EQ(early.joining.relayed_alignments, 1);
  EXPECT_FALSE(HoldsRobot3(early));
  // The same maps an align period later: a second draw agrees.
  const FusionBackend::Built later = run(2, 2, o.align_period_s);
  EXPECT_EQ(later.joining.relayed_alignments, 2);
  EXPECT_EQ(later.joining.relayed_placed, 1);
  EXPECT_TRUE(HoldsRobot3(later));
  // Robot 3's chain grew: aligned again at once, and it agrees.
  const FusionBackend::Built b = run(2, 4, 1.0);
  EXPECT_EQ(b.joining.relayed_alignments, 2);
  EXPECT_EQ(b.joining.relayed_disagreements, 0);
  EXPECT_EQ(b.joining.relayed_placed, 1);
  EXPECT_EQ(b.joining.chains, 3);
  EXPECT_EQ(b.joining.chains_joined, 3);
  EXPECT_TRUE(b.joining.solved);
  // Every landmark some robot saw, once, where it is (in our frame).
  std::set<int> seen;
  for (const auto* t : {&t1, &t2, &t3}) {
    for (const auto& v : t->seen) seen.insert(v.begin(), v.end());
  }
  EXPECT_EQ(b.global.map.size(), seen.size());
  int robot3 = 0;
  double nees = 0.0;
  for (std::size_t g = 0; g < b.global.map.size(); ++g) {
    const LandmarkOrigin& first = b.global.origins[g].front();
    const Eigen::Vector2d truth = start1.TransformTo(w.landmarks[first.id]);  // keys are the world's indices
    const Landmark& l = b.global.map.landmarks[g];
    const double e = (l.mean - truth).dot(l.cov.ldlt().solve(l.mean - truth));
    EXPECT_LT(e, 18.4) << "robot " << first.robot << " key " << first.id;  // chi-square 2 dof, 99.99 %
    nees += e;
    for (const LandmarkOrigin& x : b.global.origins[g]) robot3 += x.robot == 3 ? 1 : 0;
  }
  EXPECT_GT(robot3, 20);
  const double mean_nees = nees / static_cast<double>(b.global.map.size());
  EXPECT_GT(mean_nees, 0.5);  // one run (2.04 seen): its landmarks share a few frames' errors
  EXPECT_LT(mean_nees, 4.0);
  // The same inputs give the same map, to the bit (lockstep runs are identical).
  const FusionBackend::Built again = run(2, 4, 1.0);
  ASSERT_EQ(again.global.map.size(), b.global.map.size());
  for (std::size_t g = 0; g < b.global.map.size(); ++g) {
    EXPECT_EQ(again.global.map.landmarks[g].mean, b.global.map.landmarks[g].mean);
    EXPECT_EQ(again.global.map.landmarks[g].cov, b.global.map.landmarks[g].cov);
  }
}

// Robot 2's join puts robot 3's chain where it lies and its local map carries that placement;
// we hold robot 2 aligned, so robot 3's chain is placed at once at the two composed, once our
// maps verify it there: no alignment to search for or to confirm.
TEST_F(FusionBackendRelayed, AChainAnAlignedPeerJoinedIsPlacedWhereThePeerPutIt) {
  const FusionBackend::Built b2 = BuildRobot2();
  ASSERT_TRUE(b2.joining.solved);
  ASSERT_EQ(b2.placements.size(), 1u);  // robot 3's chain; not robot 2's own
  const ChainPlacement& p = b2.placements[0];
  EXPECT_EQ(std::pair(p.robot, p.incarnation), std::pair(RobotId{3}, 1u));
  const Pose2 truth = start2.Inverse() * start3;
  EXPECT_LT(std::hypot(p.x - truth.x, p.y - truth.y), 0.1);
  EXPECT_LT(std::abs(WrapAngle(p.theta - truth.theta)), 0.01);

  const FusionBackend::Built b = BuildOffered({{{2, 1}, b2.placements}});
  EXPECT_EQ(b.joining.relayed_by_placement, 1);
  EXPECT_EQ(b.joining.placements_refused, 0);
  EXPECT_EQ(b.joining.relayed_alignments, 0);
  EXPECT_EQ(b.joining.relayed_placed, 1);
  EXPECT_EQ(b.joining.chains_joined, 3);
  const auto [n, worst] = Robot3Landmarks(b);
  EXPECT_GT(n, 10);
  EXPECT_LT(worst, 18.4);  // chi-square 2 dof, 99.99 %
  // Our placements carry on what we joined: robot 2's chain and robot 3's.
  ASSERT_EQ(b.placements.size(), 2u);
  EXPECT_EQ(b.placements[1].robot, 3u);
}

// A placement the maps do not verify (here 3 m and 0.3 rad off) is refused and counted, and the
// chain is aligned on its own as before; one offered by a peer we have not aligned is not used.
TEST_F(FusionBackendRelayed, APlacementTheMapsRefuteOrOfAPeerNotAlignedIsNotUsed) {
  const Pose2 truth = start2.Inverse() * start3;
  const std::map<PeerKey, std::vector<ChainPlacement>> offered = {
      {{2, 1}, {{3, 1, truth.x + 3.0, truth.y, truth.theta + 0.3}}}, {{5, 1}, {{3, 1, truth.x, truth.y, truth.theta}}}};
  const FusionBackend::Built b = BuildOffered(offered);
  EXPECT_EQ(b.joining.placements_refused, 1);
  EXPECT_EQ(b.joining.relayed_by_placement, 0);
  EXPECT_EQ(b.joining.relayed_alignments, 1);
  EXPECT_EQ(b.joining.relayed_placed, 0);  // one alignment is not enough
  EXPECT_FALSE(HoldsRobot3(b));
}

// Robot 3 fell silent with its third submap open, and robot 2 relayed that open submap to us:
// it joins after robot 3's two closed ones, so our map holds every landmark robot 3's three
// submaps saw (as many as with the third one closed), each where it is; an open submap that
// does not continue the chain held (a gap before it) is not joined.
TEST_F(FusionBackendRelayed, ARelayedChainsOpenSubmapJoinsWhereItContinuesTheChain) {
  const std::map<PeerKey, std::vector<ChainPlacement>> offered = {{{2, 1}, BuildRobot2().placements}};
  const auto closed2 = Robot3Landmarks(BuildOffered(offered));
  const auto closed3 = Robot3Landmarks(BuildOffered(offered, nullptr, 3));
  ASSERT_GT(closed3.first, closed2.first);  // the third submap saw landmarks the first two did not
  const std::map<PeerKey, WireSubmap> open = {{{3, 1}, s3[2]}};
  const FusionBackend::Built b = BuildOffered(offered, &open);
  EXPECT_EQ(b.joining.relayed_placed, 1);
  EXPECT_EQ(b.joining.chains_joined, 3);
  EXPECT_EQ(b.joining.submaps, static_cast<int>(s1.size() + s2.size()) + 3);
  const auto [n, worst] = Robot3Landmarks(b);
  EXPECT_EQ(n, closed3.first);
  EXPECT_LT(worst, 18.4);  // chi-square 2 dof, 99.99 %
  // The fourth submap open while the third is not held: robot 3's two closed ones only.
  const std::map<PeerKey, WireSubmap> gap = {{{3, 1}, s3[3]}};
  const FusionBackend::Built g = BuildOffered(offered, &gap);
  EXPECT_EQ(g.joining.submaps, static_cast<int>(s1.size() + s2.size()) + 2);
  EXPECT_EQ(Robot3Landmarks(g).first, closed2.first);
}

// Robot 3's first submap was still open when robot 2 last relayed it to us: a chain held by its
// open submap alone is placed (here where robot 2's join put it) and joined like any other.
TEST_F(FusionBackendRelayed, AChainHeldOnlyByItsFirstOpenSubmapIsPlacedAndJoined) {
  const std::map<PeerKey, std::vector<ChainPlacement>> offered = {{{2, 1}, BuildRobot2().placements}};
  const std::map<PeerKey, WireSubmap> open = {{{3, 1}, s3[0]}};
  const FusionBackend::Built b = BuildOffered(offered, &open, 0);
  EXPECT_EQ(b.joining.chains_held, 3);
  EXPECT_EQ(b.joining.relayed_chains, 1);
  EXPECT_EQ(b.joining.relayed_placed, 1);
  EXPECT_EQ(b.joining.chains_joined, 3);
  EXPECT_EQ(b.joining.submaps, static_cast<int>(s1.size() + s2.size()) + 1);
  const auto [n, worst] = Robot3Landmarks(b);
  EXPECT_EQ(n, static_cast<int>(s3[0].keys.size()));
  EXPECT_LT(worst, 18.4);  // chi-square 2 dof, 99.99 %
  // Its second submap open while the first is not held: nothing of robot 3's.
  const std::map<PeerKey, WireSubmap> gap = {{{3, 1}, s3[1]}};
  EXPECT_FALSE(HoldsRobot3(BuildOffered(offered, &gap, 0)));
}

// Robot 2 fell silent after its first two submaps: the last map we took from it holds only
// their landmarks, while its third and fourth submaps reached us through relays. Its map is
// rebuilt from the chain held, so that every landmark the four saw is in our global map, once,
// where it is; a map that holds its whole chain is used as it is.
TEST_F(FusionBackendRelayed, APeersLaterSubmapsRelayedAfterItFellSilentAreInTheMap) {
  SubmapBook book;
  for (const auto* s : {&s1, &s2}) {
    for (const WireSubmap& x : *s) book.Add(x, EncodeSubmap(x));
  }
  const std::vector<MapSource> silent = {
      {2, 1, Rebuilt({s2[0], s2[1]}), start1.Inverse() * start2, 1e-6 * Eigen::Matrix3d::Identity()}};
  const FusionBackend::Built b = MakeFusionBackend(1, 1, o, 42)
                                     ->Build(own, silent, silent, {&book, nullptr, nullptr, 0.0});
  EXPECT_EQ(b.joining.chains_extended, 1);
  EXPECT_EQ(b.joining.chains_held, 2);
  EXPECT_EQ(b.joining.chains_joined, 2);
  std::set<int> seen;
  for (const auto* t : {&t1, &t2}) {
    for (const auto& v : t->seen) seen.insert(v.begin(), v.end());
  }
  ASSERT_GT(seen.size(), own.size() + silent[0].map.size() - 5);  // the later submaps saw landmarks of their own
  EXPECT_EQ(b.global.map.size(), seen.size());
  std::set<int> held;
  for (std::size_t g = 0; g < b.global.map.size(); ++g) {
    const LandmarkOrigin& first = b.global.origins[g].front();
    held.insert(static_cast<int>(first.id));  // keys are the world's indices
    const Eigen::Vector2d truth = start1.TransformTo(w.landmarks[first.id]);
    const Landmark& l = b.global.map.landmarks[g];
    EXPECT_LT((l.mean - truth).dot(l.cov.ldlt().solve(l.mean - truth)), 18.4)  // chi-square 2 dof, 99.99 %
        << "robot " << first.robot << " key " << first.id;
  }
  EXPECT_EQ(held, seen);
  // Robot 2's whole chain in its map: nothing to rebuild, the same landmarks.
  const FusionBackend::Built whole = MakeFusionBackend(1, 1, o, 42)
                                         ->Build(own, direct, direct, {&book, nullptr, nullptr, 0.0});
  EXPECT_EQ(whole.joining.chains_extended, 0);
  EXPECT_EQ(whole.global.map.size(), seen.size());
}

}  // namespace
}  // namespace mapmesh
