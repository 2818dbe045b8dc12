#include "agent/agent_node.h"
#include "agent/agent_setup.h"

#include <gtest/gtest.h>

#include <limits>
#include <nlohmann/json.hpp>
#include <random>

#include "common/config/scenario.h"
#include "common/io/checkpoint.h"
#include "common/map/submap_digest.h"
#include "tests/testing/small_submap.h"

namespace mapmesh {
namespace {

// Collects what the agent publishes.
class Capture : public AgentOutput {
 public:
  void PublishMap(const MapMessage& m) override { maps.push_back(m); }
  void PublishStatus(const AgentStatus& s) override { statuses.push_back(s); }
  std::vector<MapMessage> maps;
  std::vector<AgentStatus> statuses;
};

// The frame is the start pose (agent.frame_at_first_landmark off), so that positions below
// count from the start of the stream. In real time (the default here) peers' maps are taken as
// they arrive and the agent's own go out on its period; in lockstep both wait for ticks.
Scenario TwoRobots(bool frame_at_first_landmark = false, bool lockstep = false) {
  return ParseScenario(std::string(R"(version: 1
world: {landmarks: {list: [[5, 0], [0, 5]]}}
robots:
  list:
    - {id: 1, start: [0, 0, 0]}
    - {id: 2, start: [1, 0, 0]}
feeder: {pace: )") + (lockstep ? "lockstep" : "realtime") +
                           R"(}
agent: {map_publish_period_s: 1.0, status_period_s: 0.5, frame_at_first_landmark: )" +
                           (frame_at_first_landmark ? "true" : "false") + "}\n",
                       "test.yaml");
}

Odometry Odom(double stamp, std::uint32_t scans, bool sync = false) {
  Odometry o;
  o.robot_id = 1;
  o.seq = static_cast<std::uint32_t>(std::lround(stamp * 10)) - 1;  // 0.1 s steps from seq 0
  o.stamp = stamp;
  o.dt = 0.1;
  o.v = 1.0;
  o.w = 0.0;
  o.scans_in_interval = scans;
  o.sync = sync;
  return o;
}

Scan ScanAt(double stamp, double range, double bearing, int sig) {
  Scan s;
  s.robot_id = 1;
  s.stamp = stamp;
  s.obs.push_back({range, bearing, sig, ObservationKind::kLandmark});
  return s;
}

class AgentNodeTest : public ::testing::Test {
 protected:
  Scenario sc_ = TwoRobots();
  Capture out_;
  AgentNode node_{sc_.agent, AgentRunFor(sc_, 1), 1, 1, out_};
};

TEST_F(AgentNodeTest, WaitsForTheScansAnIntervalAnnounces) {
  node_.OnOdometry(Odom(0.1, 0));
  EXPECT_DOUBLE_EQ(node_.processed_until(), 0.1);
  node_.OnOdometry(Odom(0.2, 1));  // its scan has not arrived
  EXPECT_DOUBLE_EQ(node_.processed_until(), 0.1);
  node_.OnOdometry(Odom(0.3, 0));  // queued behind 0.2
  EXPECT_DOUBLE_EQ(node_.processed_until(), 0.1);
  // The scan at 0.15 is applied at x = 0.15 (v = 1 m/s from x = 0.1): landmark at 5 m ahead.
  node_.OnScan(ScanAt(0.15, 4.85, 0.0, 0));
  EXPECT_DOUBLE_EQ(node_.processed_until(), 0.3);
  EXPECT_EQ(node_.sync_stats().scans_processed, 1u);
  EXPECT_EQ(node_.sync_stats().odom_processed, 3u);
  const LandmarkMap m = node_.LocalMap();
  ASSERT_EQ(m.size(), 1u);
  EXPECT_NEAR(m.landmarks[0].mean.x(), 5.0, 1e-9);
  EXPECT_NEAR(node_.Pose().x, 0.3, 1e-12);
}

TEST_F(AgentNodeTest, ScansArrivingBeforeTheirOdometryAreKept) {
  node_.OnOdometry(Odom(0.1, 0));
  node_.OnScan(ScanAt(0.2, 4.8, 0.0, 0));
  node_.OnOdometry(Odom(0.2, 1));
  EXPECT_EQ(node_.sync_stats().scans_processed, 1u);
  EXPECT_NEAR(node_.LocalMap().landmarks[0].mean.x(), 5.0, 1e-9);
}

TEST_F(AgentNodeTest, TheStreamsFirstIntervalIsProcessedInFull) {
  node_.OnOdometry(Odom(0.1, 1));  // seq 0 waits for its scan
  EXPECT_EQ(node_.sync_stats().odom_processed, 0u);
  node_.OnScan(ScanAt(0.05, 4.95, 0.0, 0));
  EXPECT_EQ(node_.sync_stats().scans_processed, 1u);
  EXPECT_DOUBLE_EQ(node_.processed_until(), 0.1);
  EXPECT_DOUBLE_EQ(*node_.frame_origin_stamp(), 0.0);
  EXPECT_NEAR(node_.LocalMap().landmarks[0].mean.x(), 5.0, 1e-9);
}

TEST_F(AgentNodeTest, JoiningARunningStreamDiscardsTheFirstIntervalsScans) {
  // A restarted agent may have missed part of its first interval.
  node_.OnScan(ScanAt(3.05, 4.9, 0.0, 0));
  node_.OnOdometry(Odom(3.1, 1));  // seq 30
  EXPECT_EQ(node_.sync_stats().scans_before_start, 1u);
  EXPECT_EQ(node_.sync_stats().scans_processed, 0u);
  EXPECT_DOUBLE_EQ(node_.processed_until(), 3.1);
  EXPECT_NEAR(*node_.frame_origin_stamp(), 3.0, 1e-12);
  EXPECT_NEAR(node_.Pose().x, 0.1, 1e-12);  // the first interval still moves the pose
}

// By default the frame is the robot's pose when it first maps a landmark: the motion before
// is not applied, and the trajectory starts there.
TEST(AgentNodeFrameTest, TheFrameIsThePoseOfTheFirstScanThatMapsALandmark) {
  const Scenario sc = TwoRobots(/*frame_at_first_landmark=*/true);
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnOdometry(Odom(0.1, 0));
  node.OnOdometry(Odom(0.2, 1));
  node.OnScan(ScanAt(0.15, 4.85, 0.0, 0));  // 4.85 m ahead of the robot at 0.15 s
  node.OnOdometry(Odom(0.3, 0));
  EXPECT_DOUBLE_EQ(*node.frame_origin_stamp(), 0.15);
  ASSERT_EQ(node.LocalMap().size(), 1u);
  EXPECT_NEAR(node.LocalMap().landmarks[0].mean.x(), 4.85, 1e-9);
  EXPECT_NEAR(node.Pose().x, 0.15, 1e-12);  // moved from 0.15 s to 0.3 s only
  const auto& trajectory = node.trajectory();
  ASSERT_FALSE(trajectory.empty());
  EXPECT_GE(trajectory.front().t, 0.15);
}

TEST_F(AgentNodeTest, RejectsBadOdometryAndLateScans) {
  node_.OnOdometry(Odom(0.1, 0));
  Odometry nan = Odom(0.2, 0);
  nan.v = std::nan("");
  node_.OnOdometry(nan);
  Odometry back = Odom(0.05, 0);
  node_.OnOdometry(back);
  Odometry zero_dt = Odom(0.3, 0);
  zero_dt.dt = 0.0;
  node_.OnOdometry(zero_dt);
  EXPECT_EQ(node_.sync_stats().odom_rejected, 3u);
  node_.OnScan(ScanAt(0.05, 1.0, 0.0, 0));
  EXPECT_EQ(node_.sync_stats().scans_late, 1u);
  EXPECT_DOUBLE_EQ(node_.processed_until(), 0.1);
}

TEST_F(AgentNodeTest, GivesUpOnAScanThatNeverComes) {
  node_.OnOdometry(Odom(0.1, 0));
  node_.OnOdometry(Odom(0.2, 1));
  for (int k = 3; k < 300; ++k) node_.OnOdometry(Odom(0.1 * k, 0));
  EXPECT_EQ(node_.sync_stats().scans_missing, 0u);  // 29.9 s of odometry queued: still waiting
  for (int k = 300; k < 400; ++k) node_.OnOdometry(Odom(0.1 * k, 0));
  EXPECT_EQ(node_.sync_stats().scans_missing, 1u);
  EXPECT_GT(node_.processed_until(), 0.2);
}

TEST_F(AgentNodeTest, PublishesMapsAndStatusOnItsPeriodsAndBarriers) {
  for (int k = 1; k <= 30; ++k) node_.OnOdometry(Odom(0.1 * k, 0, k == 7));
  // Maps (local and global) at t = 0.1 (first), 1.0, 2.0, 3.0; statuses at 0.1, 0.5, 0.7
  // (sync), 1.0, ..., 3.0.
  ASSERT_EQ(out_.maps.size(), 8u);
  for (std::size_t i = 0; i < out_.maps.size(); ++i) {
    EXPECT_EQ(out_.maps[i].kind, i % 2 == 0 ? MapKind::kLocal : MapKind::kGlobal);
    EXPECT_EQ(out_.maps[i].version, i / 2 + 1);
    EXPECT_EQ(out_.maps[i].robot_id, 1u);
    EXPECT_EQ(out_.maps[i].incarnation, 1u);
    EXPECT_TRUE(DecodeMap(out_.maps[i].payload).ok());
  }
  std::vector<double> stamps;
  for (const auto& s : out_.statuses) stamps.push_back(s.processed_until);
  ASSERT_EQ(stamps.size(), 8u);
  EXPECT_NEAR(stamps[2], 0.7, 1e-12);
  EXPECT_NEAR(stamps.back(), 3.0, 1e-9);
  EXPECT_EQ(node_.stats().maps_sent, 8u);
  std::uint64_t bytes = 0;
  for (const auto& m : out_.maps) bytes += WireBytes(m);
  EXPECT_EQ(node_.stats().bytes_sent, bytes);
}

MapMessage PeerMap(RobotId from, std::vector<std::uint8_t> payload) {
  MapMessage m;
  m.robot_id = from;
  m.version = 1;
  m.payload = std::move(payload);
  return m;
}

TEST_F(AgentNodeTest, PeerMapsPassTheRadioGateOnly) {
  LandmarkMap peer;
  peer.landmarks.push_back({0, -1, {1, 2}, Eigen::Matrix2d::Identity()});
  const auto payload = EncodeMap(peer);
  node_.OnMap(PeerMap(2, payload));  // no link table yet
  EXPECT_EQ(node_.stats().maps_out_of_range, 1u);
  node_.OnLinks({0.0, {{1, 2}}});
  node_.OnMap(PeerMap(2, payload));
  EXPECT_EQ(node_.stats().maps_received, 1u);
  EXPECT_EQ(node_.stats().bytes_received, WireBytes(PeerMap(2, payload)));
  ASSERT_EQ(node_.exchange().Peers().size(), 1u);
  EXPECT_EQ(node_.exchange().Peers()[0].key.robot, 2u);
  EXPECT_EQ(node_.exchange().Peers()[0].local_landmarks, 1);
  node_.OnLinks({1.0, {}});
  node_.OnMap(PeerMap(2, payload));
  EXPECT_EQ(node_.stats().maps_out_of_range, 2u);
  EXPECT_EQ(node_.stats().maps_received, 1u);
}

TEST_F(AgentNodeTest, RejectsUnknownSendersMalformedMapsAndIgnoresItself) {
  node_.OnLinks({0.0, {{1, 2}, {1, 9}}});
  node_.OnMap(PeerMap(9, EncodeMap({})));  // robot 9 is not in the run
  EXPECT_EQ(node_.stats().maps_unknown_sender, 1u);
  node_.OnMap(PeerMap(2, {1, 2, 3}));
  EXPECT_EQ(node_.stats().maps_rejected[static_cast<int>(MapDecodeError::kTruncated)], 1u);
  node_.OnMap(PeerMap(1, EncodeMap({})));  // our own echo
  EXPECT_EQ(node_.stats().maps_received, 0u);
  EXPECT_TRUE(node_.exchange().Peers().empty());
  const AgentStatus s = node_.Status();
  EXPECT_EQ(s.maps_dropped, 2u);
}

TEST_F(AgentNodeTest, StaleVersionsAreCountedAndIgnoredPerIncarnation) {
  node_.OnLinks({0.0, {{1, 2}}});
  MapMessage m = PeerMap(2, EncodeMap({}));
  m.version = 5;
  node_.OnMap(m);
  node_.OnMap(m);  // the same version again
  m.version = 4;
  node_.OnMap(m);  // older
  EXPECT_EQ(node_.stats().maps_received, 1u);
  EXPECT_EQ(node_.stats().maps_stale_version, 2u);
  m.incarnation = 2;  // the peer restarted: a new frame, versions count afresh
  m.version = 1;
  node_.OnMap(m);
  EXPECT_EQ(node_.stats().maps_received, 2u);
  EXPECT_EQ(node_.exchange().Peers().size(), 2u);
}

TEST_F(AgentNodeTest, LivelinessMarksEveryIncarnationOfAPeerStale) {
  node_.OnLinks({0.0, {{1, 2}}});
  MapMessage m = PeerMap(2, EncodeMap({}));
  node_.OnMap(m);
  m.incarnation = 3;
  node_.OnMap(m);
  EXPECT_TRUE(node_.OnPeerLiveliness(2, false));
  EXPECT_EQ(node_.Status().peers_stale, (std::vector<RobotId>{2}));
  EXPECT_TRUE(node_.OnPeerLiveliness(2, true));
  EXPECT_TRUE(node_.Status().peers_stale.empty());
  // A robot outside the run (say a fault injector's made-up id) and the agent itself are
  // not peers: their writers coming and going changes nothing.
  EXPECT_FALSE(node_.OnPeerLiveliness(9, false));
  EXPECT_FALSE(node_.OnPeerLiveliness(1, false));
  EXPECT_TRUE(node_.Status().peers_stale.empty());
}

// An agent restarted more often than a checkpoint may hold, none of its incarnations ever
// re-merged, still writes a checkpoint its next incarnation can load: the newest ones.
TEST(AgentNodeCheckpoint, HoldsAtMostTheLoadersLimitOfEarlierIncarnationsTheNewest) {
  const Scenario sc = TwoRobots();
  const std::size_t cap = io::CheckpointLimits{}.max_earlier;
  AgentCheckpoint saved;  // as incarnation cap + 1 left it: cap earlier ones and its own
  saved.robot = 1;
  saved.incarnation = static_cast<std::uint32_t>(cap + 1);
  for (std::uint32_t inc = 1; inc <= cap; ++inc) {
    IncarnationSnapshot e;
    e.robot = 1;
    e.incarnation = inc;
    saved.earlier.push_back(e);
  }
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, static_cast<std::uint32_t>(cap + 2), out);
  node.Resume(saved);
  std::size_t left_out = 99;
  const AgentCheckpoint c = node.Checkpoint(&left_out);
  EXPECT_EQ(left_out, 1u);
  ASSERT_EQ(c.earlier.size(), cap);
  EXPECT_EQ(c.earlier.front().incarnation, 2u);  // incarnation 1, the oldest, is left out
  EXPECT_EQ(c.earlier.back().incarnation, cap + 1);
  const io::CheckpointLoad load = io::ParseCheckpoint(io::CheckpointToJson(c).dump(), "c.json", 1,
                                                      static_cast<std::uint32_t>(cap + 3));
  EXPECT_TRUE(load.ok()) << load.error;
  // Within the limit nothing is left out.
  AgentNode fresh(sc.agent, AgentRunFor(sc, 1), 1, 2, out);
  AgentCheckpoint one;
  one.robot = 1;
  one.incarnation = 1;
  fresh.Resume(one);
  EXPECT_EQ(fresh.Checkpoint(&left_out).earlier.size(), 1u);
  EXPECT_EQ(left_out, 0u);
}

// A restarted agent holds again the closed submaps its checkpoint held (its earlier chain and
// its peers'), and saves them in its own checkpoint; a robot not in this run's is refused and
// counted.
TEST(AgentNodeCheckpoint, HoldsTheSubmapsOfItsCheckpointAgainAndSavesThem) {
  const Scenario sc = TwoRobots();
  const auto submap = [](RobotId robot, std::uint32_t incarnation, std::uint32_t index) {
    return EncodeSubmap(testing::SmallSubmap(robot, incarnation, index));
  };
  AgentCheckpoint saved;
  saved.robot = 1;
  saved.incarnation = 1;
  saved.submaps = {submap(1, 1, 0), submap(1, 1, 1), submap(2, 1, 0), submap(9, 1, 0)};
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 2, out);
  node.Resume(saved);
  EXPECT_EQ(node.submaps().book().size(), 3u);
  EXPECT_EQ(node.submaps().book().ChainLength(1, 1), 2u);
  EXPECT_EQ(node.submaps().counters().restored, 3u);
  EXPECT_EQ(node.stats().submaps_refused[static_cast<int>(SubmapRefusal::kUnknownRobot)], 1u);
  std::size_t left_out = 99;
  const AgentCheckpoint c = node.Checkpoint(nullptr, &left_out);
  EXPECT_EQ(left_out, 0u);
  EXPECT_EQ(c.submaps, (std::vector<SubmapBlob>{submap(1, 1, 0), submap(1, 1, 1), submap(2, 1, 0)}));
  const io::CheckpointLoad load = io::ParseCheckpoint(io::CheckpointToJson(c).dump(), "c.json", 1, 3);
  ASSERT_TRUE(load.ok()) << load.error;
  EXPECT_EQ(load.checkpoint->submaps, c.submaps);
}

// Each bound an agent keeps on peers' maps is its own counted reason, and a refused map
// changes nothing: the peer table stays empty, and a genuine map is still taken after.
TEST(AgentNodeLimits, RefusesPeerMapsBeyondItsLimitsAndCountsWhy) {
  Scenario sc = TwoRobots();
  sc.agent.peer_limits = {/*max_landmarks=*/5, /*world_radius_m=*/1000.0, /*max_sigma_m=*/10.0};
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}}});
  auto map_of = [](int n, double x, double sigma) {
    LandmarkMap m;
    for (int i = 0; i < n; ++i) {
      m.landmarks.push_back(
          {static_cast<std::uint32_t>(i), -1, {x + i, 0.0}, sigma * sigma * Eigen::Matrix2d::Identity()});
    }
    return m;
  };
  auto refused = [&](MapRefusal r) { return node.stats().maps_refused[static_cast<int>(r)]; };
  node.OnMap(PeerMap(2, EncodeMap(map_of(6, 0.0, 0.1))));
  EXPECT_EQ(refused(MapRefusal::kTooManyLandmarks), 1u);
  node.OnMap(PeerMap(2, EncodeMap(map_of(3, 1500.0, 0.1))));
  EXPECT_EQ(refused(MapRefusal::kOutOfWorld), 1u);
  node.OnMap(PeerMap(2, EncodeMap(map_of(3, 0.0, 11.0))));
  EXPECT_EQ(refused(MapRefusal::kCovarianceTooLarge), 1u);
  MapMessage late = PeerMap(2, EncodeMap(map_of(3, 0.0, 0.1)));
  late.stamp = 1e9;
  node.OnMap(late);
  late.stamp = std::numeric_limits<double>::quiet_NaN();
  node.OnMap(late);
  EXPECT_EQ(refused(MapRefusal::kImplausibleStamp), 2u);
  MapMessage ahead = PeerMap(2, EncodeMap(map_of(3, 0.0, 0.1)));
  ahead.version = 0xFFFFFFF0u;
  node.OnMap(ahead);
  EXPECT_EQ(refused(MapRefusal::kVersionJump), 1u);
  EXPECT_TRUE(node.exchange().Peers().empty());
  EXPECT_EQ(node.stats().maps_received, 0u);
  EXPECT_EQ(node.Status().maps_dropped, 6u);
  node.OnMap(PeerMap(2, EncodeMap(map_of(3, 0.0, 0.1))));
  EXPECT_EQ(node.stats().maps_received, 1u);
}

// With fusion joining, a peer's local map carries where its join put other robots' chains.
// They are taken all or none: one implausible placement (of a robot not in the run, of the
// publisher's own chain, not finite, beyond a map's bound, out of order) refuses them all,
// counted; a later version replaces them, an earlier one changes nothing.
TEST(AgentNodeLimits, TakesAPeersChainPlacementsOnlyWhenEveryOneIsPlausible) {
  Scenario sc = TwoRobots();
  sc.agent.exchange.global.method = FusionMethod::kJoining;
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}}});
  LandmarkMap map;
  for (std::uint32_t i = 0; i < 3; ++i)
    map.landmarks.push_back({i, -1, {1.0 * i, 2.0}, 0.01 * Eigen::Matrix2d::Identity()});
  std::uint32_t version = 0;
  auto send = [&](std::vector<ChainPlacement> placements, std::uint32_t v = 0) {
    MapMessage m = PeerMap(2, EncodeMap(map));
    m.incarnation = 1;
    m.version = v != 0 ? v : ++version;
    m.placements = std::move(placements);
    node.OnMap(m);
  };
  const ChainPlacement earlier_self{1, 7, 0.5, -2.0, 0.1};  // an earlier incarnation of robot 1: plausible
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::vector<ChainPlacement>> implausible = {
      {earlier_self, {9, 1, 0.0, 0.0, 0.0}},  // robot 9 is not in the run
      {earlier_self, {2, 1, 0.0, 0.0, 0.0}},  // the publisher's own chain
      {{1, 7, 0.5, nan, 0.1}},                // not finite
      {{1, 7, 0.5, -2.0, std::numeric_limits<double>::infinity()}},
      {{1, 7, 9000.0, -2.0, 0.1}},            // beyond a map's bound
      {{2, 3, 0.0, 0.0, 0.0}, earlier_self},  // out of order
      {earlier_self, earlier_self},           // twice
      [] {                                    // more than two robots' kept incarnations, each plausible and in order
        std::vector<ChainPlacement> many;
        for (std::uint32_t i = 1; i <= 2 * 8 + 1; ++i) many.push_back({1, i, 0.5, -2.0, 0.1});
        return many;
      }()};
  for (const auto& p : implausible) send(p);
  EXPECT_EQ(node.stats().submaps_refused[static_cast<int>(SubmapRefusal::kImplausiblePlacements)], implausible.size());
  EXPECT_TRUE(node.peers_placements().empty());
  EXPECT_EQ(node.stats().maps_received, implausible.size());  // the maps themselves are taken
  const std::vector<ChainPlacement> good = {earlier_self, {2, 3, 4.0, 5.0, -3.0}};
  send(good);
  const PeerKey two{2, 1};
  ASSERT_EQ(node.peers_placements().count(two), 1u);
  EXPECT_EQ(node.peers_placements().at(two), good);
  send({earlier_self}, 2);  // an earlier version
  EXPECT_EQ(node.peers_placements().at(two), good);
  send({earlier_self});
  EXPECT_EQ(node.peers_placements().at(two), std::vector<ChainPlacement>{earlier_self});
  EXPECT_EQ(node.stats().submaps_refused[static_cast<int>(SubmapRefusal::kImplausiblePlacements)], implausible.size());
}

// Three robots in real time with fusion joining, and a one-landmark submap's bytes.
// Robots 1 .. n along the x axis, realtime, fusion joining (with the submap filter when asked).
Scenario JoiningSwarm(int n, bool submap_slam = false) {
  std::string yaml = "version: 1\nworld: {landmarks: {list: [[5, 0], [0, 5]]}}\nrobots:\n  list:\n";
  for (int i = 1; i <= n; ++i)
    yaml += "    - {id: " + std::to_string(i) + ", start: [" + std::to_string(i - 1) + ", 0, 0]}\n";
  yaml += "feeder: {pace: realtime}\nagent: {map_publish_period_s: 1.0, ";
  yaml += submap_slam ? "slam: cekf_submaps, fusion: joining}\n" : "fusion: joining}\n";
  return ParseScenario(yaml, "test.yaml");
}

Scenario JoiningTrio() { return JoiningSwarm(3); }

std::vector<std::uint8_t> OneLandmarkSubmap(RobotId robot, std::uint32_t index, double opened_s, double closed_s) {
  WireSubmap s;
  s.id = {robot, 1, index};
  s.opened_s = opened_s;
  s.closed_s = closed_s;
  s.keys = {0};
  s.x = Eigen::VectorXd::Zero(5);
  EXPECT_TRUE(s.SetCovariance(0.01 * Eigen::MatrixXd::Identity(5, 5)));
  return EncodeSubmap(s);
}

// With fusion joining, a local map carries its publisher's open submap and silent robots'
// open submaps it relays. A relayed one is taken (and counts as that robot's data reaching us)
// unless it is the publisher's own robot's (it sends its own as open_submap), a robot's not in
// the run, or ours; an open_submap that is not the publisher's is refused.
TEST(AgentNodeLimits, TakesTheOpenSubmapsAPeerRelaysOfOtherRobotsOnly) {
  Scenario sc = JoiningTrio();
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}}});
  const auto open = [](RobotId robot, double closed_s) { return OneLandmarkSubmap(robot, 0, 0.0, closed_s); };
  LandmarkMap map;
  map.landmarks.push_back({0, -1, {1.0, 2.0}, 0.01 * Eigen::Matrix2d::Identity()});
  MapMessage m = PeerMap(2, EncodeMap(map));
  m.incarnation = 1;
  m.stamp = 0.0;
  m.open_submap = open(3, 0.0);                                               // not the publisher's
  m.open_relayed = {open(2, 0.0), open(3, 5.0), open(9, 0.0), open(1, 0.0)};  // its own, 3's, 9's, ours
  node.OnMap(m);
  const auto refused = [&](SubmapRefusal r) { return node.stats().submaps_refused[static_cast<int>(r)]; };
  EXPECT_EQ(node.stats().maps_received, 1u);
  EXPECT_EQ(refused(SubmapRefusal::kNotThePublishers), 1u);
  EXPECT_EQ(refused(SubmapRefusal::kOpenRelayedByItsRobot), 1u);
  EXPECT_EQ(refused(SubmapRefusal::kUnknownRobot), 1u);
  ASSERT_EQ(node.submaps().open().size(), 1u);
  EXPECT_EQ(node.submaps().open().begin()->first, (PeerKey{3, 1}));
  EXPECT_EQ(node.stats().data_until.at(3), 5.0);
  EXPECT_EQ(node.stats().data_until.count(1), 0u);
}

// Issue R3: another participant's submaps under the agent's own identity (robot 1) were taken,
// and the agent then refused its own genuine ones as conflicts; a submap opened at -1e9 s made
// a ghost chain supersede a real one; a stale copy of a peer's map brought its riders in. Each
// is refused and counted, and nothing of them is held.
TEST(AgentNodeLimits, RefusesItsOwnRobotsSubmapsFromOthersAndRidersOfMapsNotTaken) {
  Scenario sc = JoiningTrio();
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}}});
  const auto submap = [](RobotId robot, std::uint32_t index, double opened_s) {
    return OneLandmarkSubmap(robot, index, opened_s, 0.0);
  };
  LandmarkMap map;
  map.landmarks.push_back({0, -1, {1.0, 2.0}, 0.01 * Eigen::Matrix2d::Identity()});
  MapMessage m = PeerMap(2, EncodeMap(map));
  m.incarnation = 1;
  m.version = 2;
  m.stamp = 0.0;
  m.submaps = {submap(1, 0, 0.0), submap(3, 0, -1e9), submap(3, 1, 0.0)};  // ours, opened before the run, 3's
  m.open_relayed = {submap(1, 1, 0.0)};                                    // our open one
  node.OnMap(m);
  const auto refused = [&](SubmapRefusal r) { return node.stats().submaps_refused[static_cast<int>(r)]; };
  EXPECT_EQ(node.stats().maps_received, 1u);
  EXPECT_EQ(refused(SubmapRefusal::kOwnRobot), 2u);
  EXPECT_EQ(refused(SubmapRefusal::kImplausibleStamp), 1u);
  EXPECT_EQ(node.submaps().book().Ids(), (std::vector<SubmapId>{{3, 1, 1}}));
  EXPECT_TRUE(node.submaps().open().empty());
  // The same map under an older version: stale, its riders not looked at (a new one among them).
  m.version = 1;
  m.submaps = {submap(3, 2, 0.0), submap(1, 0, 0.0)};
  m.open_relayed.clear();
  node.OnMap(m);
  EXPECT_EQ(node.stats().maps_stale_version, 1u);
  EXPECT_EQ(refused(SubmapRefusal::kOnRefusedMap), 2u);
  EXPECT_EQ(refused(SubmapRefusal::kOwnRobot), 2u);
  EXPECT_EQ(node.submaps().book().size(), 1u);
}

// Issue R3: a relay (robot 3, from its own writer: a plain run cannot refuse it) brings robot
// 2's chain with index 1 forged and an index 5 robot 2 never closed. Robot 2's own map
// advertises its chain (count 2) and the digests of both: the forged copy and the one ahead
// are dropped, counted, and robot 2's genuine index 1 is taken when it comes.
TEST(AgentNodeLimits, AnOwnersDigestsDisownTheForgeriesARelayBrought) {
  Scenario sc = JoiningTrio();
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}, {1, 3}}});
  LandmarkMap map;
  map.landmarks.push_back({0, -1, {1.0, 2.0}, 0.01 * Eigen::Matrix2d::Identity()});
  const std::vector<std::uint8_t> g0 = OneLandmarkSubmap(2, 0, 0.0, 0.1), g1 = OneLandmarkSubmap(2, 1, 0.1, 0.2);
  MapMessage relay = PeerMap(3, EncodeMap(map));
  relay.incarnation = 1;
  relay.stamp = 0.0;
  relay.submaps = {g0, OneLandmarkSubmap(2, 1, 0.1, 0.25), OneLandmarkSubmap(2, 5, 0.1, 0.2)};
  node.OnMap(relay, "w3");
  EXPECT_EQ(node.submaps().book().ChainLength(2, 1), 2u);
  MapMessage owner = PeerMap(2, EncodeMap(map));
  owner.incarnation = 1;
  owner.stamp = 0.0;
  owner.submaps_held = {{2, 1, 2}};
  owner.own_submap_digests = {SubmapDigest(g0), SubmapDigest(g1)};
  node.OnMap(owner, "w2");
  EXPECT_EQ(node.submaps().counters().owner_conflicts, 1u);
  EXPECT_EQ(node.submaps().counters().ahead_of_owner, 1u);
  EXPECT_EQ(node.submaps().book().Ids(), (std::vector<SubmapId>{{2, 1, 0}}));
  owner.version = 2;
  owner.submaps = {g1};
  node.OnMap(owner, "w2");
  EXPECT_EQ(node.submaps().book().ChainLength(2, 1), 2u);
  EXPECT_EQ(*node.submaps().book().Bytes({2, 1, 1}), g1);
}

// Issue R3: submaps bounded in bytes. A peer's closed or open submap longer than
// agent.max_submap_bytes is refused unread (too_large) and nothing of it is held; one within
// is taken. The agent's own submaps close before they outgrow that bound.
// The transport's bound on a sample (Cyclone's MaxSampleSize, issue R3): with the defaults, a
// little above a map at the peers' limits with a publication's submaps (1.5 MB), below the 4 MB
// of two 500-landmark submaps; it grows with what the settings let a publisher send, and with the
// link table of a large run.
TEST(AgentNodeLimits, TheSampleBoundFollowsWhatThePublishersMaySend) {
  Scenario sc = JoiningTrio();
  const AgentRun run = AgentRunFor(sc, 1);
  const std::size_t bound = AgentNode::MaxSampleBytes(sc.agent, run);
  const std::size_t peer_map = kMapCodecLandmarkBytes * sc.agent.peer_limits.max_landmarks;
  const auto& sub = sc.agent.exchange.submaps;
  EXPECT_GE(bound, peer_map + 3 * sub.max_submap_bytes + 2 * sub.send_bytes);
  EXPECT_LT(bound, 2 * SubmapPayloadBytes(kSubmapCodecMaxLandmarks));
  Scenario more = sc;
  more.agent.exchange.submaps.send_bytes = 16u << 20;
  EXPECT_GE(AgentNode::MaxSampleBytes(more.agent, run), 32u << 20);
  more = sc;
  more.agent.peer_limits.max_landmarks = 100000;
  EXPECT_GE(AgentNode::MaxSampleBytes(more.agent, run) - bound, 90000 * kMapCodecLandmarkBytes);
  AgentRun large = run;
  large.robots.clear();
  for (RobotId r = 1; r <= 2000; ++r) large.robots.push_back(r);
  EXPECT_GE(AgentNode::MaxSampleBytes(sc.agent, large), 8u * 2000 * 1999 / 2);
}

TEST(AgentNodeLimits, RefusesSubmapsLongerThanTheByteLimitAndClosesItsOwnWithin) {
  Scenario sc = JoiningTrio();
  sc.agent.exchange.submaps.max_submap_bytes = SubmapPayloadBytes(3);
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}}});
  const auto submap = [](RobotId robot, std::uint32_t index, int landmarks) {
    WireSubmap s;
    s.id = {robot, 1, index};
    for (int i = 0; i < landmarks; ++i) s.keys.push_back(static_cast<std::uint32_t>(i));
    s.x = Eigen::VectorXd::Zero(3 + 2 * landmarks);
    EXPECT_TRUE(s.SetCovariance(0.01 * Eigen::MatrixXd::Identity(3 + 2 * landmarks, 3 + 2 * landmarks)));
    return EncodeSubmap(s);
  };
  LandmarkMap map;
  map.landmarks.push_back({0, -1, {1.0, 2.0}, 0.01 * Eigen::Matrix2d::Identity()});
  MapMessage m = PeerMap(2, EncodeMap(map));
  m.incarnation = 1;
  m.stamp = 0.0;
  m.submaps = {submap(3, 0, 3), submap(3, 1, 4)};  // within, one landmark beyond
  m.open_submap = submap(2, 0, 4);
  m.open_relayed = {submap(3, 2, 4)};
  node.OnMap(m);
  EXPECT_EQ(node.stats().maps_received, 1u);
  EXPECT_EQ(node.stats().submaps_refused[static_cast<int>(SubmapRefusal::kTooLarge)], 3u);
  EXPECT_EQ(node.submaps().book().Ids(), (std::vector<SubmapId>{{3, 1, 0}}));
  EXPECT_TRUE(node.submaps().open().empty());

  // The own mapper closes a submap 16 landmarks short of the bound: with room for 20, at 4.
  std::string yaml = "version: 1\nworld: {landmarks: {list: [";
  for (int i = 0; i < 40; ++i)
    yaml += (i ? ", [" : "[") + std::to_string(2 + i % 20) + ", " + (i < 20 ? "3" : "-3") + "]";
  yaml += "]}}\nrobots:\n  list:\n    - {id: 1, start: [0, 0, 0]}\n";
  yaml += "feeder: {pace: realtime}\nagent: {slam: cekf_submaps, fusion: joining, submap_distance_m: 0,";
  yaml += " max_submap_bytes: " + std::to_string(SubmapPayloadBytes(20)) + "}\n";
  const Scenario dense = ParseScenario(yaml, "dense.yaml");
  const std::unique_ptr<LocalMapper> mapper = MakeLocalMapper(dense, 1);
  std::vector<Observation> obs;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector2d p(2 + i % 20, i < 20 ? 3 : -3);
    obs.push_back({p.norm(), std::atan2(p.y(), p.x()), i, ObservationKind::kLandmark});
  }
  // Each scan sees two landmarks it has not seen yet, the robot at rest.
  for (int k = 0; k < 10; ++k) {
    mapper->Predict({0.0, 0.0}, 0.1);
    mapper->Observe({obs.begin() + 2 * k, obs.begin() + 2 * k + 2}, 0.1 * (k + 1));
  }
  ASSERT_GT(mapper->SubmapsClosed(), 0u);
  const std::optional<WireSubmap> first = mapper->ClosedSubmap(0, {1, 1, 0});
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->keys.size(), 4u);
  EXPECT_LE(EncodeSubmap(*first).size(), SubmapPayloadBytes(20));
}

// A stand-in for the secure runs' signatures (transport::SubmapSigner): robot r's signature
// over bytes is {r, their sum mod 256}; robots 1 to 3 have certificates, others none.
class FakeOrigin final : public SubmapOrigin {
 public:
  explicit FakeOrigin(RobotId self) : self_(self) {}
  static std::vector<std::uint8_t> Of(RobotId robot, std::span<const std::uint8_t> bytes) {
    unsigned sum = 0;
    for (std::uint8_t b : bytes) sum += b;
    return {static_cast<std::uint8_t>(robot), static_cast<std::uint8_t>(sum & 0xff)};
  }
  std::vector<std::uint8_t> Sign(std::span<const std::uint8_t> bytes) override { return Of(self_, bytes); }
  Verdict Verify(RobotId origin, std::span<const std::uint8_t> bytes, std::span<const std::uint8_t> sig) override {
    ++verified;
    if (sig.empty()) return Verdict::kUnsigned;
    if (origin < 1 || origin > 3) return Verdict::kUnknownSigner;
    const std::vector<std::uint8_t> want = Of(origin, bytes);
    return std::equal(sig.begin(), sig.end(), want.begin(), want.end()) ? Verdict::kValid : Verdict::kForged;
  }
  int verified = 0;

 private:
  RobotId self_;
};

// Issue R3, secure runs: a submap enters only with the signature of the robot it claims,
// whoever relays it; relays send it on with that signature; the same bytes again are a
// duplicate, not checked again; different bytes under a held identity that are not its
// robot's count as forged, never as a conflict (which would say the robot made two); an
// edited checkpoint's submap is refused at Resume.
TEST(AgentNodeLimits, SecureRunsTakeOnlySubmapsSignedByTheRobotTheyClaim) {
  const Scenario sc = JoiningSwarm(4, /*submap_slam=*/true);
  Capture out;
  FakeOrigin origin(1);
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.SetSubmapOrigin(&origin);
  node.OnLinks({0.0, {{1, 2}}});
  const auto signed_by = [](RobotId signer, std::vector<std::uint8_t> bytes) {
    std::vector<std::uint8_t> sig = FakeOrigin::Of(signer, bytes);
    return SubmapBlob{std::move(bytes), std::move(sig)};
  };
  LandmarkMap map;
  map.landmarks.push_back({0, -1, {1.0, 2.0}, 0.01 * Eigen::Matrix2d::Identity()});
  MapMessage m = PeerMap(2, EncodeMap(map));
  m.incarnation = 1;
  m.stamp = 0.0;
  m.submaps_held = {{2, 1, 1}};  // its own chain (an owner's word on it: SubmapRelay::OnOwnerAdvert)
  m.submaps = {signed_by(3, OneLandmarkSubmap(3, 0, 0.0, 0.0)),  // relayed, 3's own signature
               signed_by(2, OneLandmarkSubmap(3, 1, 0.0, 0.0)),  // 3's index signed by the relay
               OneLandmarkSubmap(3, 2, 0.0, 0.0),                // unsigned
               signed_by(4, OneLandmarkSubmap(4, 0, 0.0, 0.0)),  // a robot without a certificate
               signed_by(2, OneLandmarkSubmap(2, 0, 0.0, 0.0))};
  m.open_submap = OneLandmarkSubmap(2, 1, 0.0, 0.0);
  m.open_submap_signature = FakeOrigin::Of(2, m.open_submap);
  m.open_relayed = {signed_by(2, OneLandmarkSubmap(3, 1, 0.0, 0.0))};  // 3's open one, signed by the relay
  node.OnMap(m);
  const auto refused = [&](SubmapRefusal r) { return node.stats().submaps_refused[static_cast<int>(r)]; };
  EXPECT_EQ(node.submaps().book().Ids(), (std::vector<SubmapId>{{2, 1, 0}, {3, 1, 0}}));
  EXPECT_EQ(refused(SubmapRefusal::kForgedSignature), 2u);
  EXPECT_EQ(refused(SubmapRefusal::kUnsigned), 1u);
  EXPECT_EQ(refused(SubmapRefusal::kUnknownSigner), 1u);
  ASSERT_EQ(node.submaps().open().size(), 1u);
  EXPECT_EQ(node.submaps().open().begin()->first, (PeerKey{2, 1}));
  EXPECT_EQ(origin.verified, 7);
  // The held ones again, unsigned: duplicates, not checked; one of them changed and signed by
  // the relay: forged, no conflict; the same open submap: not checked again.
  m.version = 2;
  m.submaps = {OneLandmarkSubmap(3, 0, 0.0, 0.0), signed_by(2, OneLandmarkSubmap(3, 0, 0.0, 1.0))};
  m.open_relayed.clear();
  node.OnMap(m);
  EXPECT_EQ(origin.verified, 8);
  EXPECT_EQ(node.submaps().counters().duplicates, 1u);
  EXPECT_EQ(node.submaps().counters().conflicts, 0u);
  EXPECT_EQ(refused(SubmapRefusal::kForgedSignature), 3u);
  // What it sends on carries the robots' signatures: 3's relayed to robot 2 (which advertised
  // none), and its own open submap signed by robot 1.
  const auto step = [&node](int k) {  // robot 1 stands still, seeing the landmark at (5, 0)
    node.OnScan(ScanAt(0.1 * k - 0.05, 5.0, 0.0, -1));
    node.OnOdometry(Odom(0.1 * k, 1));
  };
  for (int k = 1; k <= 5; ++k) step(k);
  m.version = 3;
  m.stamp = 0.5;
  m.submaps.clear();
  m.submaps_held = {{2, 1, 1}};
  node.OnMap(m);  // robot 2's advertisement since: it holds its own chain only
  for (int k = 6; k <= 25; ++k) step(k);
  int relayed = 0, open_signed = 0;
  for (const MapMessage& sent : out.maps) {
    for (const SubmapBlob& b : sent.submaps) {
      const SubmapDecodeResult d = DecodeSubmap(b.bytes);
      ASSERT_TRUE(d.ok());
      EXPECT_EQ(b.signature, FakeOrigin::Of(d.submap.id.robot, b.bytes));
      ++relayed;
    }
    if (!sent.open_submap.empty()) {
      EXPECT_EQ(sent.open_submap_signature, FakeOrigin::Of(1, sent.open_submap));
      ++open_signed;
    }
  }
  EXPECT_GT(relayed, 0);
  EXPECT_GT(open_signed, 0);
  // A checkpoint's submaps: one edited after it was signed is refused, the others held.
  AgentCheckpoint c = node.Checkpoint();
  ASSERT_EQ(c.submaps.size(), 2u);
  c.submaps[1].bytes = OneLandmarkSubmap(3, 0, 0.0, 0.5);  // 3.1.0 edited, its signature kept
  Capture out2;
  FakeOrigin origin2(1);
  AgentNode resumed(sc.agent, AgentRunFor(sc, 1), 1, 2, out2);
  resumed.SetSubmapOrigin(&origin2);
  resumed.Resume(c);
  EXPECT_EQ(resumed.submaps().book().Ids(), (std::vector<SubmapId>{{2, 1, 0}}));
  EXPECT_EQ(resumed.stats().submaps_refused[static_cast<int>(SubmapRefusal::kForgedSignature)], 1u);
}

// One reading 30 km away (beyond what the 8 m sensor sees) never reaches the map, and the
// agent keeps publishing.
TEST(AgentNodeLimits, AReadingBeyondTheSensorsRangeIsRefused) {
  Scenario sc = TwoRobots();
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnScan(ScanAt(0.05, 30000.0, 0.0, -1));
  node.OnOdometry(Odom(0.1, 1));
  EXPECT_EQ(node.mapper().stats().out_of_range, 1u);
  EXPECT_EQ(node.LocalMap().size(), 0u);
  for (int k = 2; k <= 20; ++k) node.OnOdometry(Odom(0.1 * k, 0));
  EXPECT_GT(out.maps.size(), 0u);
  EXPECT_EQ(node.stats().maps_encode_failed, 0u);
}

// ----- the lockstep exchange (messages.h ExchangeTick) ---------------------------------------

// Collects sightings too.
class FullCapture : public Capture {
 public:
  void PublishSighting(const Sighting& s) override { sightings.push_back(s); }
  std::vector<Sighting> sightings;
};

// A tick whose link table joins robot 1 to 2, 3 and 4 (stamp 0).
ExchangeTick Tick(std::uint32_t index, TickPhase phase, std::vector<TickPeer> peers,
                  RadioLinks links = {0.0, {{1, 2}, {1, 3}, {1, 4}}}) {
  ExchangeTick t;
  t.index = index;
  t.stamp = index * 1.0;
  t.phase = phase;
  t.links = std::move(links);
  t.peers = std::move(peers);
  return t;
}

MapMessage TaggedMap(RobotId from, std::uint32_t incarnation, MapKind kind, std::uint32_t version, std::uint32_t tick,
                     const LandmarkMap& map) {
  MapMessage m = PeerMap(from, EncodeMap(map));
  m.incarnation = incarnation;
  m.kind = kind;
  m.version = version;
  m.tick = tick;
  return m;
}

LandmarkMap Points(std::initializer_list<Eigen::Vector2d> points) {
  LandmarkMap m;
  std::uint32_t id = 0;
  for (const Eigen::Vector2d& p : points) m.landmarks.push_back({id++, -1, p, 0.01 * Eigen::Matrix2d::Identity()});
  return m;
}

class LockstepTest : public ::testing::Test {
 protected:
  Scenario sc_ = TwoRobots(false, true);
  FullCapture out_;
  AgentNode node_{sc_.agent, AgentRunFor(sc_, 1), 1, 1, out_};
  const std::vector<TickPeer> both_ = {{1, 1, 0}, {2, 1, 0}};
};

// Nothing goes out between ticks: the agent's maps wait for the exchange phase, which publishes
// them tagged, and its status reports the tick done and how many messages went out.
TEST_F(LockstepTest, MapsGoOutOnlyAtTicksTaggedWithThem) {
  ASSERT_TRUE(AgentRunFor(sc_, 1).exchange_ticks);
  for (int k = 1; k <= 30; ++k) node_.OnOdometry(Odom(0.1 * k, 0));
  EXPECT_TRUE(out_.maps.empty());  // three map periods went by
  ASSERT_TRUE(node_.OnTick(Tick(3, TickPhase::kExchange, both_)));
  ASSERT_EQ(out_.maps.size(), 2u);
  for (const MapMessage& m : out_.maps) EXPECT_EQ(m.tick, 3u);
  ASSERT_FALSE(out_.statuses.empty());
  EXPECT_EQ(out_.statuses.back().tick_done, 3u);
  EXPECT_EQ(out_.statuses.back().tick_published, 2u);
  // The same tick again (sent again to a late reader) does nothing.
  EXPECT_TRUE(node_.OnTick(Tick(3, TickPhase::kExchange, both_)));
  EXPECT_EQ(out_.maps.size(), 2u);
  // A tick that does not list this incarnation is not for it.
  EXPECT_TRUE(node_.OnTick(Tick(4, TickPhase::kExchange, {{1, 7, 0}, {2, 1, 0}})));
  EXPECT_EQ(out_.maps.size(), 2u);
}

// Two robots in lockstep, maps every second; `radio` the radio section's keys, `agent` more of
// the agent section's.
Scenario LockstepPair(const std::string& radio, const std::string& agent = "") {
  return ParseScenario(R"(version: 1
world: {landmarks: {list: [[5, 0], [0, 5]]}}
robots:
  list:
    - {id: 1, start: [0, 0, 0]}
    - {id: 2, start: [1, 0, 0]}
feeder: {pace: lockstep}
radio: {)" + radio + R"(}
agent: {map_publish_period_s: 1.0, frame_at_first_landmark: false)" +
                           agent + "}\n",
                       "test.yaml");
}

// A joining agent's peers use its local map and submaps only: its global map stays off the
// wire, and the tick counts the one map that went out.
TEST(LockstepJoiningTest, AJoiningAgentPublishesItsLocalMapOnly) {
  const Scenario sc = LockstepPair("", ", slam: cekf_submaps, fusion: joining");
  FullCapture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  for (int k = 1; k <= 30; ++k) node.OnOdometry(Odom(0.1 * k, 0));
  ASSERT_TRUE(node.OnTick(Tick(3, TickPhase::kExchange, {{1, 1, 0}, {2, 1, 0}})));
  ASSERT_EQ(out.maps.size(), 1u);
  EXPECT_EQ(out.maps[0].kind, MapKind::kLocal);
  EXPECT_TRUE(DecodeMap(out.maps[0].payload).ok());
  EXPECT_EQ(out.statuses.back().tick_published, 1u);
  EXPECT_EQ(node.stats().maps_sent, 1u);
  EXPECT_EQ(node.stats().bytes_sent, WireBytes(out.maps[0]));
}

// Peers' maps wait in the inbox and count for nothing until the next exchange phase applies
// them; a deliver phase holds until every message it lists has arrived.
TEST_F(LockstepTest, PeersMapsWaitForTheNextTickAndDeliveryWaitsForEveryListedMessage) {
  node_.OnLinks({0.0, {{1, 2}}});
  const LandmarkMap peer = Points({{1, 2}, {3, 1}});
  ASSERT_TRUE(node_.OnTick(Tick(1, TickPhase::kExchange, both_)));
  EXPECT_FALSE(node_.OnTick(Tick(1, TickPhase::kDeliver, {{1, 1, 2}, {2, 1, 2}})));
  node_.OnMap(TaggedMap(2, 1, MapKind::kLocal, 1, 1, peer));
  EXPECT_FALSE(node_.OnTick(Tick(1, TickPhase::kDeliver, {{1, 1, 2}, {2, 1, 2}})));
  ASSERT_EQ(node_.Missing(Tick(1, TickPhase::kDeliver, {{1, 1, 2}, {2, 1, 2}})).size(), 1u);
  node_.OnMap(TaggedMap(2, 1, MapKind::kGlobal, 1, 1, peer));
  node_.OnMap(TaggedMap(2, 1, MapKind::kGlobal, 1, 1, peer));  // twice: kept once
  EXPECT_TRUE(node_.OnTick(Tick(1, TickPhase::kDeliver, {{1, 1, 2}, {2, 1, 2}})));
  EXPECT_EQ(out_.statuses.back().tick_delivered, 1u);
  EXPECT_EQ(node_.stats().maps_received, 0u);  // not applied yet
  ASSERT_TRUE(node_.OnTick(Tick(2, TickPhase::kExchange, both_)));
  EXPECT_EQ(node_.stats().maps_received, 2u);
  EXPECT_EQ(node_.stats().maps_stale_version, 0u);
  // A map of a tick already applied, sent again to a late reader, is not taken again.
  node_.OnMap(TaggedMap(2, 1, MapKind::kGlobal, 1, 1, peer));
  ASSERT_TRUE(node_.OnTick(Tick(3, TickPhase::kExchange, both_)));
  EXPECT_EQ(node_.stats().maps_received, 2u);
  EXPECT_EQ(node_.stats().maps_stale_version, 0u);
}

// Issue R3 (forged_relay): a map claiming a robot incarnation from another DDS writer than the
// one its maps were taken from is refused on arrival, before it can take the robot's map key
// for a tick, and the robot's own map of that tick is then taken. One kept before the robot's
// first map was taken is refused when applied, its riders with it.
TEST_F(LockstepTest, AMapFromAnotherWriterThanTheRobotsIsRefusedAndTakesNoKey) {
  node_.OnLinks({0.0, {{1, 2}}});
  const LandmarkMap peer = Points({{1, 2}, {3, 1}}), moved = Points({{9, 2}, {3, 7}});
  const auto refused = [&] { return node_.stats().maps_refused[static_cast<int>(MapRefusal::kOtherWriter)]; };
  ASSERT_TRUE(node_.OnTick(Tick(1, TickPhase::kExchange, both_)));
  // Before robot 2's first map is taken, both are kept: the forger's at tick 2, 2's own at 1.
  MapMessage early = TaggedMap(2, 1, MapKind::kLocal, 3, 2, moved);
  early.submaps = {OneLandmarkSubmap(2, 0, 0.0, 0.0)};
  node_.OnMap(early, "forger");
  node_.OnMap(TaggedMap(2, 1, MapKind::kLocal, 1, 1, peer), "robot2");
  ASSERT_TRUE(node_.OnTick(Tick(2, TickPhase::kExchange, both_)));  // takes 2's tick-1 map: bound
  EXPECT_EQ(node_.stats().maps_received, 1u);
  EXPECT_EQ(refused(), 0u);
  // The forger writes robot 2's next key (tick 2, version 2) before robot 2 does: refused.
  node_.OnMap(TaggedMap(2, 1, MapKind::kLocal, 2, 2, moved), "forger");
  EXPECT_EQ(refused(), 1u);
  node_.OnMap(TaggedMap(2, 1, MapKind::kLocal, 2, 2, peer), "robot2");
  EXPECT_EQ(node_.inbox_refused()[static_cast<std::size_t>(InboxRefusal::kKeyTaken)], 0u);
  ASSERT_TRUE(node_.OnTick(Tick(3, TickPhase::kExchange, both_)));
  // Robot 2's tick-2 map taken; the forger's kept before the binding refused when applied.
  EXPECT_EQ(node_.stats().maps_received, 2u);
  EXPECT_EQ(refused(), 2u);
  EXPECT_EQ(node_.stats().submaps_refused[static_cast<int>(SubmapRefusal::kOnRefusedMap)], 1u);
  EXPECT_TRUE(node_.submaps().book().Ids().empty());
  const auto received = node_.exchange().ReceivedMaps();
  ASSERT_EQ(received.size(), 1u);
  ASSERT_NE(received[0].local, nullptr);
  EXPECT_EQ(received[0].local->landmarks.at(0).mean, peer.landmarks.at(0).mean);
  // A restarted robot 2 (a new incarnation) speaks from its new writer.
  node_.OnMap(TaggedMap(2, 2, MapKind::kLocal, 1, 3, peer), "robot2-restarted");
  EXPECT_EQ(refused(), 2u);
}

TEST(AgentNodeLimits, InRealTimeAMapFromAnotherWriterThanTheRobotsIsRefused) {
  Scenario sc = TwoRobots();
  Capture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
  node.OnLinks({0.0, {{1, 2}}});
  LandmarkMap m;
  m.landmarks.push_back({0, -1, {1.0, 2.0}, 0.01 * Eigen::Matrix2d::Identity()});
  MapMessage first = PeerMap(2, EncodeMap(m));
  first.incarnation = 1;
  node.OnMap(first, "robot2");
  MapMessage next = first;
  next.version = 2;
  node.OnMap(next, "forger");
  EXPECT_EQ(node.stats().maps_refused[static_cast<int>(MapRefusal::kOtherWriter)], 1u);
  node.OnMap(next, "");  // an unknown writer is not judged
  node.OnMap(next, "robot2");
  EXPECT_EQ(node.stats().maps_received, 2u);
  EXPECT_EQ(node.stats().maps_stale_version, 1u);
}

// Rendezvous in lockstep: the agent's sightings ride on its tick's local map (no message of
// their own), and a peer's reach its tracker at the next tick; one riding on another robot's
// map, or of another tick, is refused.
TEST_F(LockstepTest, SightingsRideOnTheTicksMaps) {
  Scan sees2;
  sees2.robot_id = 1;
  sees2.stamp = 0.05;
  sees2.obs.push_back({1.0, 0.0, 2, ObservationKind::kRobot});
  node_.OnScan(sees2);
  for (int k = 1; k <= 10; ++k) node_.OnOdometry(Odom(0.1 * k, k == 1 ? 1 : 0));
  ASSERT_TRUE(node_.OnTick(Tick(1, TickPhase::kExchange, both_)));
  EXPECT_TRUE(out_.sightings.empty());  // no sighting message of its own
  ASSERT_EQ(out_.maps.size(), 2u);
  ASSERT_EQ(out_.maps[0].kind, MapKind::kLocal);
  ASSERT_EQ(out_.maps[0].sightings.size(), 1u);
  EXPECT_TRUE(out_.maps[1].sightings.empty());
  const Sighting& mine = out_.maps[0].sightings[0];
  EXPECT_EQ(mine.robot_id, 1u);
  EXPECT_EQ(mine.other, 2u);
  EXPECT_EQ(mine.tick, 1u);
  EXPECT_EQ(node_.stats().sightings_sent, 1u);
  EXPECT_EQ(out_.statuses.back().tick_published, 2u);  // the maps: what the deliver phase waits for
  // Robot 2's map with its sighting of robot 1, one claiming robot 3 and one of another tick.
  Sighting theirs = mine;
  theirs.robot_id = 2;
  theirs.other = 1;
  MapMessage m = TaggedMap(2, 1, MapKind::kLocal, 1, 1, Points({{1, 2}, {3, 1}}));
  Sighting forged = theirs, late = theirs;
  forged.robot_id = 3;
  late.tick = 0;
  m.sightings = {theirs, forged, late};
  node_.OnMap(m);
  EXPECT_EQ(node_.stats().sightings_implausible, 2u);
  EXPECT_EQ(node_.stats().sightings_received, 0u);  // not before the next tick
  ASSERT_TRUE(node_.OnTick(Tick(1, TickPhase::kDeliver, {{1, 1, 2}, {2, 1, 1}})));
  ASSERT_TRUE(node_.OnTick(Tick(2, TickPhase::kExchange, both_)));
  EXPECT_EQ(node_.stats().sightings_received, 1u);
  EXPECT_EQ(node_.rendezvous_stats().sightings_used, 1u);  // answered at the tick
  ASSERT_EQ(out_.maps.size(), 4u);
  ASSERT_EQ(out_.maps[2].sightings.size(), 1u);
  EXPECT_EQ(out_.maps[2].sightings[0].kind, SightingKind::kAnswer);
  EXPECT_EQ(out_.maps[2].sightings[0].tick, 2u);
}

// The gates judge a tick's messages by the tick's link table, whatever came in on the links
// topic: out of range there, a peer's map is dropped though the latest table joins them.
TEST_F(LockstepTest, TheGatesUseTheTicksLinkTable) {
  ASSERT_TRUE(node_.OnTick(Tick(1, TickPhase::kExchange, both_)));
  node_.OnMap(TaggedMap(2, 1, MapKind::kLocal, 1, 1, Points({{1, 2}, {3, 1}})));
  node_.OnLinks({1.5, {{1, 2}}});
  ASSERT_TRUE(node_.OnTick(Tick(2, TickPhase::kExchange, both_, {2.0, {}})));
  EXPECT_EQ(node_.stats().maps_out_of_range, 1u);
  EXPECT_EQ(node_.stats().maps_received, 0u);
}

// Two robots in lockstep, every link 2.5 s long.
class LockstepLatencyTest : public ::testing::Test {
 protected:
  Scenario sc = LockstepPair("latency_s: 2.5");
  FullCapture out;
  AgentNode node{sc.agent, AgentRunFor(sc, 1), 1, 1, out};
  const std::vector<TickPeer> both = {{1, 1, 0}, {2, 1, 0}};
};

// U1 (radio.latency_s): a peer's map that passed the gate waits until it has arrived over its
// link, the first tick at or after its stamp plus the link's latency: 1 s + 2.5 s, tick 4.
TEST_F(LockstepLatencyTest, APeersMapIsTakenAtTheFirstTickAfterItArrives) {
  ASSERT_TRUE(node.OnTick(Tick(1, TickPhase::kExchange, both)));
  MapMessage m = TaggedMap(2, 1, MapKind::kLocal, 1, 1, Points({{1, 2}, {3, 1}}));
  m.stamp = 1.0;
  node.OnMap(m);
  ASSERT_TRUE(node.OnTick(Tick(2, TickPhase::kExchange, both)));
  EXPECT_EQ(node.stats().maps_delayed, 1u);  // passed the gate, in flight
  EXPECT_EQ(node.stats().in_flight, 1u);
  EXPECT_EQ(node.stats().maps_received, 0u);
  ASSERT_TRUE(node.OnTick(Tick(3, TickPhase::kExchange, both)));
  EXPECT_EQ(node.stats().maps_received, 0u);
  ASSERT_TRUE(node.OnTick(Tick(4, TickPhase::kExchange, both)));
  EXPECT_EQ(node.stats().maps_received, 1u);
  EXPECT_EQ(node.stats().in_flight, 0u);
  EXPECT_EQ(node.stats().data_until.at(2), 1.0);
  EXPECT_EQ(node.stats().MapsDropped(), 0u);
}

// Out of range when it was sent: dropped by the gate, never held.
TEST_F(LockstepLatencyTest, AMapTheGateDropsIsNeverHeld) {
  ASSERT_TRUE(node.OnTick(Tick(1, TickPhase::kExchange, both)));
  node.OnMap(TaggedMap(2, 1, MapKind::kLocal, 1, 1, Points({{1, 2}, {3, 1}})));
  ASSERT_TRUE(node.OnTick(Tick(2, TickPhase::kExchange, both, {2.0, {}})));
  EXPECT_EQ(node.stats().maps_out_of_range, 1u);
  EXPECT_EQ(node.stats().maps_delayed, 0u);
  EXPECT_EQ(node.stats().in_flight, 0u);
}

// The ticks say who is alive: DDS liveliness is not used, and a peer incarnation missing from a
// tick is stale from then on.
TEST_F(LockstepTest, LivelinessComesFromTheTicks) {
  node_.OnLinks({0.0, {{1, 2}}});
  EXPECT_FALSE(node_.OnPeerLiveliness(2, false));
  ASSERT_TRUE(node_.OnTick(Tick(1, TickPhase::kExchange, both_)));
  node_.OnMap(TaggedMap(2, 1, MapKind::kLocal, 1, 1, Points({{1, 2}, {3, 1}})));
  ASSERT_TRUE(node_.OnTick(Tick(2, TickPhase::kExchange, both_)));
  ASSERT_EQ(node_.exchange().Peers().size(), 1u);
  EXPECT_FALSE(node_.exchange().Peers()[0].stale);
  ASSERT_TRUE(node_.OnTick(Tick(3, TickPhase::kExchange, {{1, 1, 0}})));
  EXPECT_TRUE(node_.exchange().Peers()[0].stale);
  EXPECT_EQ(node_.Status().peers_stale, (std::vector<RobotId>{2}));
}

// A restarted incarnation's readers get the writers' history: messages of ticks before its
// first are not for it; untagged ones (from outside the run's agents) are taken at the next tick.
TEST(LockstepRestartTest, MessagesOfTicksBeforeTheFirstAreLeftOut) {
  const Scenario sc = TwoRobots(false, true);
  FullCapture out;
  AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 2, out);
  node.OnLinks({0.0, {{1, 2}}});
  node.OnMap(TaggedMap(2, 1, MapKind::kLocal, 7, 7, Points({{1, 2}, {3, 1}})));  // from before we were up
  MapMessage untagged = TaggedMap(2, 1, MapKind::kGlobal, 7, 0, Points({{1, 2}}));
  node.OnMap(untagged);
  ASSERT_TRUE(node.OnTick(Tick(9, TickPhase::kExchange, {{1, 2, 0}, {2, 1, 0}})));
  EXPECT_EQ(node.stats().maps_received, 1u);  // the untagged one
  ASSERT_EQ(node.exchange().Peers().size(), 1u);
  EXPECT_EQ(node.exchange().Peers()[0].local_landmarks, 0);
}

// Peers' messages applied at a tick give the same state whatever order they arrived in: over
// seeded shuffles of three peers' maps and sightings, the global maps and statuses are equal.
TEST(LockstepOrderTest, ArrivalOrderChangesNothing) {
  const Scenario sc = ParseScenario(R"(version: 1
world: {landmarks: {list: [[5, 0], [0, 5], [4, 4], [6, 2], [2, 6]]}}
robots:
  list:
    - {id: 1, start: [0, 0, 0]}
    - {id: 2, start: [1, 0, 0]}
    - {id: 3, start: [0, 1, 0]}
    - {id: 4, start: [1, 1, 0]}
agent: {map_publish_period_s: 1.0}
)",
                                    "test.yaml");
  std::vector<MapMessage> maps;
  for (RobotId r = 2; r <= 4; ++r) {
    const double dx = 0.05 * r;
    const LandmarkMap m = Points({{5 + dx, 0}, {0 + dx, 5}, {4 + dx, 4}, {6 + dx, 2}, {2 + dx, 6}});
    maps.push_back(TaggedMap(r, 1, MapKind::kLocal, 1, 1, m));
    maps.push_back(TaggedMap(r, 1, MapKind::kGlobal, 1, 1, m));
  }
  const std::vector<TickPeer> all = {{1, 1, 0}, {2, 1, 0}, {3, 1, 0}, {4, 1, 0}};
  auto run = [&](std::vector<MapMessage> arrival) {
    FullCapture out;
    AgentNode node(sc.agent, AgentRunFor(sc, 1), 1, 1, out);
    node.OnLinks({0.0, {{1, 2}, {1, 3}, {1, 4}}});
    node.OnScan(ScanAt(0.05, 5.0, 0.0, 0));
    node.OnOdometry(Odom(0.1, 1));
    EXPECT_TRUE(node.OnTick(Tick(1, TickPhase::kExchange, all)));
    for (const MapMessage& m : arrival) node.OnMap(m);
    EXPECT_TRUE(node.OnTick(Tick(2, TickPhase::kExchange, all)));
    return std::make_pair(nlohmann::json(node.exchange().Peers().size()).dump() + " " +
                              std::to_string(node.stats().maps_received),
                          out.maps);
  };
  const auto reference = run(maps);
  EXPECT_EQ(reference.first, "3 6");       // every map applied, three peers
  ASSERT_EQ(reference.second.size(), 4u);  // two ticks' maps
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<MapMessage> shuffled = maps;
    std::shuffle(shuffled.begin(), shuffled.end(), rng);
    const auto got = run(shuffled);
    EXPECT_EQ(got.first, reference.first);
    ASSERT_EQ(got.second.size(), reference.second.size());
    for (std::size_t i = 0; i < got.second.size(); ++i) EXPECT_EQ(got.second[i].payload, reference.second[i].payload);
  }
}

}  // namespace
}  // namespace mapmesh