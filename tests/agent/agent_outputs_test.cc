#include "agent/agent_outputs.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "agent/agent_setup.h"
#include "common/config/scenario.h"
#include "common/map/map_codec.h"

namespace mapmesh {
namespace {

namespace fs = std::filesystem;

class Discard : public AgentOutput {
 public:
  void PublishMap(const MapMessage&) override {}
  void PublishStatus(const AgentStatus&) override {}
};

// Robot 1 at the origin sees eight trees; robot 2 is its peer. Realtime, maps every second.
Scenario Pair() {
  return ParseScenario(R"(version: 1
world: {landmarks: {list: [[5, 0], [0, 5], [4, 4], [6, 2], [2, 6], [3, -4], [-2, 5], [5, -2]]}}
robots:
  list:
    - {id: 1, start: [0, 0, 0]}
    - {id: 2, start: [1, 0, 0]}
feeder: {pace: realtime}
agent: {map_publish_period_s: 1.0, frame_at_first_landmark: false}
)",
                       "test.yaml");
}

Odometry Still(double stamp, std::uint32_t scans) {
  Odometry o;
  o.robot_id = 1;
  o.seq = static_cast<std::uint32_t>(std::lround(stamp * 10)) - 1;
  o.stamp = stamp;
  o.dt = 0.1;
  o.scans_in_interval = scans;
  return o;
}

// Each tree once, from the origin, with its signature.
Scan SeesEveryTree(const Scenario& sc, double stamp) {
  Scan s;
  s.robot_id = 1;
  s.stamp = stamp;
  for (const Eigen::Vector2d& p : sc.world.landmarks)
    s.obs.push_back({p.norm(), std::atan2(p.y(), p.x()), -1, ObservationKind::kLandmark});
  return s;
}

std::string Read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class AgentOutputsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("agent_outputs_test_" + std::to_string(::testing::UnitTest::GetInstance()->current_test_info()->line()));
    fs::remove_all(dir_);
    node_.OnLinks({0.0, {{1, 2}}});
    node_.OnScan(SeesEveryTree(sc_, 0.05));
    for (int k = 1; k <= 12; ++k) node_.OnOdometry(Still(0.1 * k, k == 1 ? 1 : 0));
  }
  void TearDown() override { fs::remove_all(dir_); }
  // Robot 2's map: the trees in its own frame, 2 m to the right and turned by 0.3 rad; its first
  // map holds six of them, the later ones all (a second alignment on new pairs confirms the first).
  MapMessage PeerMap(std::uint32_t version) const {
    const Pose2 to_own{2.0, 0.0, 0.3};
    const Pose2 from_own = to_own.Inverse();
    LandmarkMap m;
    std::uint32_t id = 0;
    for (const Eigen::Vector2d& p : sc_.world.landmarks) {
      if (version == 1 && id == 6) break;
      m.landmarks.push_back({id++, -1, from_own.Apply(p), 0.01 * Eigen::Matrix2d::Identity()});
    }
    MapMessage msg;
    msg.robot_id = 2;
    msg.incarnation = 1;
    msg.version = version;
    msg.payload = EncodeMap(m);
    return msg;
  }

  Scenario sc_ = Pair();
  Discard out_;
  AgentNode node_{sc_.agent, AgentRunFor(sc_, 1), 1, 7, out_};
  fs::path dir_;
};

TEST_F(AgentOutputsTest, StatsCarryTheNodesStateAndTheShellsCounts) {
  ShellCounts shell;
  shell.maps_impersonated[3] = 2;
  shell.links_not_from_feeder = 4;
  shell.oversize_dropped = 5;
  shell.max_sample_bytes = 1234;
  shell.peers_lost_wall[2] = 17.5;
  OutputHealth health;
  const io::json s = StatsJson(node_, shell, health);
  EXPECT_EQ(s.at("id"), 1);
  EXPECT_EQ(s.at("incarnation"), 7);
  EXPECT_DOUBLE_EQ(s.at("processed_until").get<double>(), node_.processed_until());
  EXPECT_EQ(s.at("odom_processed"), node_.sync_stats().odom_processed);
  EXPECT_EQ(s.at("scans_processed"), 1);
  EXPECT_EQ(s.at("local_landmarks"), node_.LocalMap().size());
  EXPECT_EQ(node_.LocalMap().size(), 8u);
  EXPECT_EQ(s.at("impersonations_refused").at("maps").at("3"), 2);
  EXPECT_TRUE(s.at("impersonations_refused").at("sightings").empty());
  EXPECT_EQ(s.at("not_from_feeder").at("links"), 4);
  EXPECT_EQ(s.at("not_from_feeder").at("ticks"), 0);
  EXPECT_EQ(s.at("transport_oversize").at("dropped"), 5);
  EXPECT_EQ(s.at("transport_oversize").at("max_sample_bytes"), 1234);
  EXPECT_DOUBLE_EQ(s.at("peers_lost_wall").at("2").get<double>(), 17.5);
  EXPECT_TRUE(s.at("outputs").at("stopped_at").is_null());
  // Every refusal reason is a key, counted or not.
  EXPECT_EQ(s.at("maps_refused").size(), static_cast<std::size_t>(kMapRefusalCount));
  EXPECT_EQ(s.at("inbox_refused").size(), static_cast<std::size_t>(kInboxRefusalCount));

  ASSERT_TRUE(health.Failed(io::WriteError("/full/disk", ENOSPC), 1.2));
  EXPECT_FALSE(health.Failed(io::WriteError("/full/disk", ENOSPC), 3.0));  // counted, not logged again
  const io::json failed = StatsJson(node_, shell, health);
  EXPECT_EQ(failed.at("outputs").at("write_failures"), 2);
  EXPECT_DOUBLE_EQ(failed.at("outputs").at("stopped_at").get<double>(), 1.2);
  EXPECT_NE(failed.at("outputs").at("reason").get<std::string>().find("/full/disk"), std::string::npos);
}

TEST_F(AgentOutputsTest, EachWriteLeavesTheMapsStatsSnapshotsAndAHistoryLineAndTheLastThePeersMaps) {
  node_.OnMap(PeerMap(1));
  WriteOutputs(node_, dir_.string(), {}, {}, /*final=*/false);
  EXPECT_FALSE(fs::exists(dir_ / "peers"));
  for (int k = 13; k <= 20; ++k) node_.OnOdometry(Still(0.1 * k, 0));
  WriteOutputs(node_, dir_.string(), {}, {}, /*final=*/true);
  for (const char* f : {"local_map.json", "global_map.json", "stats.json", "trajectory.json"})
    EXPECT_TRUE(fs::exists(dir_ / f)) << f;
  const io::json stats = io::json::parse(Read(dir_ / "stats.json"));
  EXPECT_EQ(stats.at("final"), true);
  EXPECT_EQ(io::json::parse(Read(dir_ / "local_map.json")), io::MapToJson(node_.LocalMap()));
  std::istringstream history(Read(dir_ / "history.jsonl"));
  std::vector<io::json> lines;
  for (std::string line; std::getline(history, line);) lines.push_back(io::json::parse(line));
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0].at("final"), false);
  EXPECT_EQ(lines[1].at("final"), true);
  EXPECT_LT(lines[0].at("t").get<double>(), lines[1].at("t").get<double>());
  EXPECT_EQ(lines[1].at("local_landmarks"), stats.at("local_landmarks"));
  EXPECT_EQ(lines[1].at("maps_received"), 1);
  for (const io::json& l : lines) {
    const std::string snapshot = l.at("snapshot");
    EXPECT_TRUE(fs::exists(dir_ / (snapshot + "_local.json"))) << snapshot;
    EXPECT_TRUE(fs::exists(dir_ / (snapshot + "_global.json"))) << snapshot;
    EXPECT_NE(snapshot.find("_i7"), std::string::npos);  // the incarnation
  }
  EXPECT_TRUE(fs::exists(dir_ / "peers" / "2_1_local.json"));
}

TEST_F(AgentOutputsTest, AWriteThatCannotBeDoneThrowsWriteError) {
  fs::create_directories(dir_);
  std::ofstream(dir_ / "file") << "not a directory";
  EXPECT_THROW(WriteOutputs(node_, (dir_ / "file" / "agent").string(), {}, {}, false), io::WriteError);
}

// The log tells when a peer is aligned (accepted, then confirmed by the next verification),
// once, with the transform found; nothing while the exchange has not updated.
TEST_F(AgentOutputsTest, ThePeerEventLogTellsAnAlignmentOnceWithItsTransform) {
  PeerEventLog log;
  EXPECT_TRUE(log.Update(node_).empty());
  std::vector<std::string> lines;
  std::uint32_t version = 0;
  for (int k = 13; k <= 100; ++k) {
    if (k % 10 == 3) node_.OnMap(PeerMap(++version));  // a map a second, as robot 2 publishes
    node_.OnOdometry(Still(0.1 * k, 0));
    const std::uint64_t updates = node_.exchange().updates();
    const std::vector<std::string> now = log.Update(node_);
    lines.insert(lines.end(), now.begin(), now.end());
    EXPECT_TRUE(log.Update(node_).empty());  // the same update: told once
    if (node_.exchange().updates() == updates) {
      EXPECT_TRUE(log.Update(node_).empty());
    }
  }
  ASSERT_TRUE(node_.exchange().Peers().at(0).aligned);
  ASSERT_EQ(lines.size(), 1u);
  const std::size_t at = lines[0].find("s peer 2.1: aligned at (");
  ASSERT_NE(at, std::string::npos) << lines[0];
  double x = 0, y = 0, deg = 0;
  ASSERT_EQ(std::sscanf(lines[0].c_str() + at, "s peer 2.1: aligned at (%lf m, %lf m, %lf deg)", &x, &y, &deg), 3)
      << lines[0];
  EXPECT_NEAR(x, 2.0, 0.01);
  EXPECT_NEAR(y, 0.0, 0.01);
  EXPECT_NEAR(deg, RadToDeg(0.3), 0.01);
}

// Refused input is told with how many since the last line, at most once every 5 s, and looked
// at once a second.
TEST_F(AgentOutputsTest, TheInputWatchTellsWhatWasRefusedSinceItsLastLineAtMostEveryFiveSeconds) {
  InputWatch watch;
  EXPECT_FALSE(watch.Check(node_, 100.0));
  MapMessage bad = PeerMap(1);
  bad.payload = {1, 2, 3};
  node_.OnMap(bad);
  EXPECT_FALSE(watch.Check(node_, 100.5));  // looked at once a second
  const std::optional<std::string> line = watch.Check(node_, 101.0);
  ASSERT_TRUE(line);
  EXPECT_NE(line->find("input refused or lost: 1 peer maps malformed"), std::string::npos) << *line;
  node_.OnMap(bad);
  node_.OnMap(bad);
  EXPECT_FALSE(watch.Check(node_, 105.9));
  const std::optional<std::string> next = watch.Check(node_, 106.0);
  ASSERT_TRUE(next);
  EXPECT_NE(next->find(": 2 peer maps malformed"), std::string::npos) << *next;
}

}  // namespace
}  // namespace mapmesh
