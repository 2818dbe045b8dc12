#include "common/config/scenario.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <set>

#include "common/config/config_error.h"
#include "tests/config/scenario_testing.h"

namespace mapmesh {
namespace {

namespace fs = std::filesystem;

class ScenarioTest : public testing::TempDirTest {
 protected:
  std::string Write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p.string();
  }
  // The ConfigError message of loading text, or "" when it loads.
  std::string ErrorOf(const std::string& text, const std::vector<ConfigOverride>& o = {}) {
    const std::string path = Write("s.yaml", text);
    try {
      LoadScenario(path, o);
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  }
};

constexpr const char* kMinimal = R"(version: 1
world:
  landmarks:
    list: [[0, 0], [5, 5], [10, 0]]
robots:
  list:
    - id: 1
      start: [0, 0, 90]
)";

TEST_F(ScenarioTest, MinimalScenarioGetsDefaults) {
  const Scenario s = LoadScenario(Write("min.yaml", kMinimal));
  EXPECT_EQ(s.name, "min");
  EXPECT_EQ(s.world.landmarks.size(), 3u);
  ASSERT_EQ(s.robots.size(), 1u);
  const RobotSpec& r = s.robots[0];
  EXPECT_EQ(r.id, 1u);
  EXPECT_NEAR(r.start.theta, M_PI / 2, 1e-12);
  // Thesis defaults (ALGORITHMS.md section 1).
  EXPECT_DOUBLE_EQ(r.motion.speed_mps, 0.3);
  EXPECT_DOUBLE_EQ(r.motion.max_turn_rate_dps, 30.0);
  EXPECT_DOUBLE_EQ(r.motion.sigma_v_mps, 0.03);
  EXPECT_DOUBLE_EQ(r.motion.sigma_w_radps, 0.0524);
  EXPECT_DOUBLE_EQ(r.sensor.max_range_m, 8.0);
  EXPECT_DOUBLE_EQ(r.sensor.fov_deg, 180.0);
  EXPECT_DOUBLE_EQ(r.sensor.sigma_range_m, 0.05);
  EXPECT_DOUBLE_EQ(r.sensor.sigma_bearing_deg, 1.0);
  EXPECT_EQ(r.sensor.scan_every_steps, 5);
  EXPECT_FALSE(r.sensor.signatures);
  EXPECT_DOUBLE_EQ(s.world.control_period_s, 0.1);
  EXPECT_EQ(r.path.type, PathType::kRandom);
  EXPECT_EQ(r.path.points.size(), 8u);
  for (const auto& p : r.path.points) EXPECT_TRUE(s.world.bounds_m.Contains(p));
}

// The agents' liveliness lease: 1 s up to 16 robots, robots / 16 s beyond, unless given.
TEST_F(ScenarioTest, LivelinessLeaseGrowsWithTheSwarmUnlessGiven) {
  const std::string path = Write("min.yaml", kMinimal);
  for (const auto& [agents, lease] : std::vector<std::pair<int, double>>{{1, 1.0}, {16, 1.0}, {24, 1.5}, {64, 4.0}}) {
    const Scenario s = LoadScenario(path, {}, agents);
    EXPECT_DOUBLE_EQ(s.agent.LivelinessLeaseS(s.robots.size()), lease) << agents;
  }
  const Scenario given = LoadScenario(path, {ParseOverride("agent.liveliness_lease_s=2.5")}, 64);
  EXPECT_DOUBLE_EQ(given.agent.LivelinessLeaseS(given.robots.size()), 2.5);
  EXPECT_NE(ErrorOf(kMinimal, {ParseOverride("agent.liveliness_lease_s=0.01")}).find("liveliness_lease_s"),
            std::string::npos);
}

// agent.fusion takes every fusion method's name, the robust ones included.
TEST_F(ScenarioTest, FusionTakesTheOgkMethods) {
  const std::string path = Write("min.yaml", kMinimal);
  EXPECT_EQ(LoadScenario(path).agent.exchange.global.method, FusionMethod::kCiConstant);
  EXPECT_EQ(LoadScenario(path, {ParseOverride("agent.fusion=ogk")}).agent.exchange.global.method, FusionMethod::kOgk);
  EXPECT_EQ(LoadScenario(path, {ParseOverride("agent.fusion=ci_ogk")}).agent.exchange.global.method,
            FusionMethod::kCiOgk);
  EXPECT_NE(ErrorOf(kMinimal, {ParseOverride("agent.fusion=ogk2")}).find("fusion"), std::string::npos);
}

// agent.align_search picks the alignment's transform search; RANSAC unless given.
TEST_F(ScenarioTest, AlignSearchIsReadIntoTheExchangesAlignment) {
  EXPECT_EQ(ParseScenario(kMinimal, "s.yaml", {}, 0).agent.exchange.align.search, TransformSearch::kRansac);
  EXPECT_EQ(ParseScenario(kMinimal, "s.yaml", {ParseOverride("agent.align_search=arw")}, 0).agent.exchange.align.search,
            TransformSearch::kAdaptiveRandomWalk);
  EXPECT_EQ(ParseScenario(kMinimal, "s.yaml", {ParseOverride("agent.align_search=its")}, 0).agent.exchange.align.search,
            TransformSearch::kIterativeTranslation);
  EXPECT_NE(ErrorOf(kMinimal, {ParseOverride("agent.align_search=icp")}).find("align_search"), std::string::npos);
}

TEST_F(ScenarioTest, UnknownKeyNamesFileLineAndKey) {
  const std::string text = std::string(kMinimal) + "      sensor:\n        max_range_m: 5\n        colour: red\n";
  const std::string err = ErrorOf(text);
  EXPECT_NE(err.find("s.yaml:11: robots.list[0].sensor.colour: unknown key"), std::string::npos) << err;
}

TEST_F(ScenarioTest, UnknownTopLevelKey) {
  const std::string err = ErrorOf(std::string(kMinimal) + "radioo: {range_m: 3}\n");
  EXPECT_NE(err.find("s.yaml:9: radioo: unknown key"), std::string::npos) << err;
}

TEST_F(ScenarioTest, NegativeSensorRange) {
  const std::string err = ErrorOf(std::string(kMinimal) + "      sensor: {max_range_m: -2}\n");
  EXPECT_NE(err.find("s.yaml:9: robots.list[0].sensor.max_range_m: must be >= 0 (got -2)"), std::string::npos) << err;
}

TEST_F(ScenarioTest, WrongType) {
  const std::string err = ErrorOf(std::string(kMinimal) + "duration_s: soon\n");
  EXPECT_NE(err.find("s.yaml:9: duration_s: expected a number, got 'soon'"), std::string::npos) << err;
  const std::string err2 = ErrorOf(std::string(kMinimal) + "seed: -4\n");
  EXPECT_NE(err2.find("s.yaml:9: seed: must be a non-negative integer"), std::string::npos) << err2;
}

TEST_F(ScenarioTest, MissingLandmarksFile) {
  const std::string err = ErrorOf(R"(version: 1
world:
  landmarks:
    csv: nowhere.csv
robots: {count: 1}
)");
  EXPECT_NE(err.find("s.yaml:4: world.landmarks.csv: cannot open landmarks file"), std::string::npos) << err;
  EXPECT_NE(err.find("nowhere.csv"), std::string::npos) << err;
}

TEST_F(ScenarioTest, LandmarksCsvIsResolvedBesideTheScenario) {
  Write("lm.csv", "x,y\n# a comment\n1.5, 2\n\n3,4\n");
  const Scenario s = LoadScenario(Write("c.yaml", R"(version: 1
world:
  landmarks: {csv: lm.csv}
robots: {count: 2}
)"));
  ASSERT_EQ(s.world.landmarks.size(), 2u);
  EXPECT_DOUBLE_EQ(s.world.landmarks[0].x(), 1.5);
  EXPECT_DOUBLE_EQ(s.world.landmarks[1].y(), 4.0);
  EXPECT_EQ(s.robots.size(), 2u);
}

TEST_F(ScenarioTest, MalformedCsvRowNamesTheCsvLine) {
  Write("bad.csv", "1,2\n3,oops\n");
  const std::string err = ErrorOf("version: 1\nworld:\n  landmarks: {csv: bad.csv}\nrobots: {count: 1}\n");
  EXPECT_NE(err.find("bad.csv:2: expected 'x,y'"), std::string::npos) << err;
}

TEST_F(ScenarioTest, OtherBadValues) {
  EXPECT_NE(ErrorOf("version: 2\n").find("s.yaml:1: version: unsupported"), std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kMinimal) + "    - id: 1\n").find("s.yaml:9: robots.list[1].id: duplicate robot id"),
            std::string::npos);
  EXPECT_NE(ErrorOf(std::string(kMinimal) + "radio: {loss_probability: 1.5}\n")
                .find("radio.loss_probability: must be <= 1 (got 1.5)"),
            std::string::npos);
  EXPECT_NE(
      ErrorOf(std::string(kMinimal) + "feeder: {pace: warp}\n").find("feeder.pace: must be one of lockstep, realtime"),
      std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nworld:\n  landmarks:\n    list: [[0, 0]]\n    csv: a.csv\nrobots: {count: 1}\n")
                .find("world.landmarks: give exactly one of"),
            std::string::npos);
  EXPECT_NE(ErrorOf("world: {landmarks: {list: [[1, 2, 3]]}}\nrobots: {count: 1}\n")
                .find("world.landmarks.list[0]: expected a point"),
            std::string::npos);
  EXPECT_NE(
      ErrorOf(
          "world: {landmarks: {generator: {count: 5000, area_m: [0, 0, 10, 10], min_spacing_m: 1}}}\nrobots: {count: 1}\n")
          .find("world.landmarks.generator.count: cannot place 5000"),
      std::string::npos);
  EXPECT_NE(ErrorOf("world: {landmarks: {list: []}}\n").find("the scenario has no robots"), std::string::npos);
  EXPECT_NE(ErrorOf("world: [\n").find("s.yaml:"), std::string::npos);  // YAML syntax error
}

TEST_F(ScenarioTest, OverridesApplyAndAreReportedAsSuch) {
  const std::string path = Write("o.yaml", kMinimal);
  const Scenario s = LoadScenario(path, {ParseOverride("radio.range_m=0"),
                                         ParseOverride("robots.list[0].sensor.max_range_m=12")});
  EXPECT_DOUBLE_EQ(s.radio.range_m, 0.0);
  EXPECT_DOUBLE_EQ(s.robots[0].sensor.max_range_m, 12.0);
  const std::string err = ErrorOf(kMinimal, {ParseOverride("robots.list[0].sensor.max_range_m=-1")});
  EXPECT_NE(err.find("--set robots.list[0].sensor.max_range_m: must be >= 0"), std::string::npos) << err;
  EXPECT_NE(ErrorOf(kMinimal, {ParseOverride("radio.rnage_m=3")}).find("--set radio.rnage_m: unknown key"),
            std::string::npos);
  EXPECT_THROW(ParseOverride("novalue"), ConfigError);
}

TEST_F(ScenarioTest, AgentsScalesTheRobotListDeterministically) {
  const std::string path = Write("g.yaml", R"(version: 1
seed: 11
world:
  landmarks:
    generator: {count: 50, area_m: [0, 0, 30, 20]}
robots:
  count: 2
  list:
    - id: 4
      start: [1, 1, 0]
      path: {type: waypoints, points: [[5, 5], [10, 5]]}
)");
  const Scenario two = LoadScenario(path);
  ASSERT_EQ(two.robots.size(), 2u);
  EXPECT_EQ(two.robots[0].id, 4u);
  EXPECT_EQ(two.robots[1].id, 5u);
  const Scenario eight = LoadScenario(path, {}, 8);
  ASSERT_EQ(eight.robots.size(), 8u);
  // Robot k is the same whatever N is, and generated robots stay in the world.
  EXPECT_EQ(eight.robots[1].start.x, two.robots[1].start.x);
  EXPECT_EQ(eight.robots[1].path.points, two.robots[1].path.points);
  for (const RobotSpec& r : eight.robots) {
    EXPECT_TRUE(eight.world.bounds_m.Contains({r.start.x, r.start.y}));
  }
  EXPECT_EQ(eight.robots[0].path.points.size(), 2u);
  EXPECT_EQ(LoadScenario(path, {}, 1).robots.size(), 1u);
  // A different seed moves the generated robots.
  const Scenario other = LoadScenario(path, {ParseOverride("seed=12")}, 8);
  EXPECT_NE(other.robots[3].start.x, eight.robots[3].start.x);
}

TEST_F(ScenarioTest, ShippedScenariosLoad) {
  for (const auto& entry : fs::directory_iterator(MAPMESH_SOURCE_DIR "/scenarios")) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW(LoadScenario(entry.path().string()));
  }
}

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

TEST(PathWaypoints, CircleStartsOnTheCircleFacingAlongIt) {
  PathOptions p;
  p.type = PathType::kCircle;
  p.center_m = {1, 2};
  p.radius_m = 5;
  p.count = 4;
  p.start_angle_deg = 90;
  Pose2 start;
  const auto pts = CircleWaypoints(p, &start);
  ASSERT_EQ(pts.size(), 4u);
  EXPECT_NEAR(start.x, 1.0, 1e-12);
  EXPECT_NEAR(start.y, 7.0, 1e-12);
  EXPECT_NEAR(start.theta, -M_PI, 1e-12);  // counter-clockwise at the top: heading west
  EXPECT_NEAR(pts[0].x(), -4.0, 1e-12);    // a quarter turn on
  EXPECT_NEAR(pts[3].y(), 7.0, 1e-12);     // and back to the start
  p.clockwise = true;
  CircleWaypoints(p, &start);
  EXPECT_NEAR(start.theta, 0.0, 1e-12);
}

TEST(PathWaypoints, LawnmowerSweepsLanes) {
  const auto pts = LawnmowerWaypoints({0, 0, 20, 10}, 5);
  ASSERT_EQ(pts.size(), 6u);  // lanes at y = 0, 5, 10
  EXPECT_EQ(pts[0], Eigen::Vector2d(0, 0));
  EXPECT_EQ(pts[1], Eigen::Vector2d(20, 0));
  EXPECT_EQ(pts[2], Eigen::Vector2d(20, 5));
  EXPECT_EQ(pts[3], Eigen::Vector2d(0, 5));
  EXPECT_EQ(pts[5], Eigen::Vector2d(20, 10));
}

class ScenarioExtrasTest : public ::testing::Test {
 protected:
  std::string ErrorOf(const std::string& text) {
    try {
      ParseScenario(text, "x.yaml");
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  }
};

TEST_F(ScenarioExtrasTest, PathTypesResolveAndRejectForeignKeys) {
  const Scenario s = ParseScenario(R"(world: {landmarks: {list: [[0, 0]]}}
robots:
  list:
    - {id: 1, path: {type: circle, center_m: [0, 0], radius_m: 5}}
    - {id: 2, path: {type: lawnmower, area_m: [0, 0, 10, 10], spacing_m: 5}}
)",
                                   "x.yaml");
  EXPECT_EQ(s.robots[0].path.points.size(), 36u);
  EXPECT_NEAR(s.robots[0].start.x, 5.0, 1e-12);
  EXPECT_EQ(s.robots[1].path.points.size(), 6u);
  EXPECT_NE(
      ErrorOf("world: {landmarks: {list: [[0, 0]]}}\nrobots: {list: [{id: 1, path: {type: circle, spacing_m: 3}}]}\n")
          .find("robots.list[0].path.spacing_m: not used by path type circle"),
      std::string::npos);
}

TEST_F(ScenarioExtrasTest, PresetsSetMotionAndSensor) {
  const Scenario s = ParseScenario(R"(world: {landmarks: {list: [[0, 0]]}}
robots:
  defaults: {preset: downs}
  list:
    - {id: 1}
    - {id: 2, preset: thesis, sensor: {max_range_m: 11}}
)",
                                   "x.yaml");
  EXPECT_DOUBLE_EQ(s.robots[0].motion.speed_mps, 1.0);
  EXPECT_DOUBLE_EQ(s.robots[0].sensor.max_range_m, 10.0);
  EXPECT_DOUBLE_EQ(s.robots[0].sensor.fov_deg, 45.0);
  EXPECT_DOUBLE_EQ(s.robots[1].motion.speed_mps, 0.3);
  EXPECT_DOUBLE_EQ(s.robots[1].sensor.max_range_m, 11.0);
  EXPECT_NE(ErrorOf("world: {landmarks: {list: [[0, 0]]}}\nrobots: {defaults: {preset: fast}, count: 1}\n")
                .find("robots.defaults.preset: must be one of thesis, downs"),
            std::string::npos);
}

// X1: what a run was made with. Every value key read is resolved: given in the file, overridden,
// or its default; numbers as the shortest text that reads back to them.
TEST_F(ScenarioExtrasTest, EveryKeyReadIsResolvedWithTheValueTaken) {
  std::set<std::string> keys;
  const Scenario s = ParseScenario(R"(world: {landmarks: {list: [[0, 0]]}}
radio: {range_m: 11}
robots:
  list:
    - {id: 1, path: {type: circle, center_m: [0, 0], radius_m: 5}}
)",
                                   "x.yaml", {ParseOverride("seed=4"), ParseOverride("agent.align_period_s=0.1")}, 0,
                                   &keys);
  const ResolvedScenario& r = s.resolved;
  using K = ResolvedValue::Kind;
  EXPECT_EQ(r.at("radio.range_m"), (ResolvedValue{K::kNumber, "11"}));  // given
  EXPECT_EQ(r.at("seed"), (ResolvedValue{K::kNumber, "4"}));            // overridden
  EXPECT_EQ(r.at("agent.align_period_s"), (ResolvedValue{K::kNumber, "0.1"}));
  EXPECT_EQ(r.at("duration_s"), (ResolvedValue{K::kNumber, "60"}));  // defaults
  EXPECT_EQ(r.at("feeder.pace"), (ResolvedValue{K::kString, "lockstep"}));
  EXPECT_EQ(r.at("feeder.keep_streams"), (ResolvedValue{K::kBool, "true"}));
  EXPECT_EQ(r.at("robots.list[0].path.center_m"), (ResolvedValue{K::kYaml, "[0, 0]"}));
  EXPECT_EQ(r.at("robots.list[0].path.radius_m"), (ResolvedValue{K::kNumber, "5"}));
  EXPECT_EQ(r.at("world.landmarks.list").kind, K::kYaml);
  EXPECT_EQ(s.seed, 4u);
  // Each resolved key is one the loader reads (list indices as []), and nearly every key it
  // reads here is resolved (those left out are lists read whole and absent).
  std::set<std::string> resolved_keys;
  for (const auto& [key, v] : r) resolved_keys.insert(std::regex_replace(key, std::regex(R"(\[[0-9]+\])"), "[]"));
  for (const std::string& key : resolved_keys) EXPECT_TRUE(keys.count(key)) << key;
  EXPECT_GT(resolved_keys.size(), 0.8 * static_cast<double>(keys.size()));
}

// X1: the fault schedule saved with the experiment; each entry checked where it is written.
TEST_F(ScenarioExtrasTest, FaultsAreReadEntryByEntryAndCheckedInOneLine) {
  const std::string head = "world: {landmarks: {list: [[0, 0]]}}\nduration_s: 60\nrobots: {count: 3}\n";
  const Scenario s = ParseScenario(head + R"(faults:
  kill: [{id: 3, t: 20}, {id: 2, t: 40}]
  restart: [{id: 3, t: 35}]
  pause: [{id: 1, t: 30, seconds: 2.5}]
  inject: {cases: "stale,huge", period_s: 0.5}
)",
                                   "x.yaml");
  using K = FaultEvent::Kind;
  ASSERT_EQ(s.faults.events.size(), 4u);
  EXPECT_EQ(s.faults.events[0].kind, K::kKill);
  EXPECT_EQ(s.faults.events[0].id, 3u);
  EXPECT_EQ(s.faults.events[0].t, 20.0);
  EXPECT_EQ(s.faults.events[1].id, 2u);
  EXPECT_EQ(s.faults.events[2].kind, K::kRestart);
  EXPECT_EQ(s.faults.events[3].kind, K::kPause);
  EXPECT_EQ(s.faults.events[3].seconds, 2.5);
  EXPECT_EQ(s.faults.inject, "stale,huge");
  EXPECT_EQ(s.faults.inject_period_s, 0.5);
  EXPECT_TRUE(ParseScenario(head, "x.yaml").faults.events.empty());
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"faults: {kill: [{id: 3}]}", "faults.kill[0].t: missing required key"},
      {"faults: {kill: [{id: 0, t: 5}]}", "faults.kill[0].id: must be >= 1"},
      {"faults: {restart: [{id: 3, t: 61}]}", "faults.restart[0].t: must be <= 60"},
      {"faults: {pause: [{id: 3, t: 5}]}", "faults.pause[0].seconds: missing required key"},
      {"faults: {pause: [{id: 3, t: 5, seconds: 0}]}", "faults.pause[0].seconds: must be > 0"},
      {"faults: {kill: [{id: 3, t: 5, when: 2}]}", "faults.kill[0].when: unknown key"},
      {"faults: {kill: [3@5]}", "faults.kill[0]: expected a mapping of keys"},
      {"faults: {crash: []}", "faults.crash: unknown key"},
  };
  for (const auto& [text, expected] : bad) {
    EXPECT_NE(ErrorOf(head + text + "\n").find(expected), std::string::npos) << text << ": " << ErrorOf(head + text);
  }
}

TEST_F(ScenarioExtrasTest, DatasetSourcesDecideTheRobots) {
  const Scenario m = ParseScenario("source: {type: mrclam, robots: [2, 4]}\n", "m.yaml");
  ASSERT_EQ(m.robots.size(), 2u);
  EXPECT_EQ(m.robots[1].id, 4u);
  EXPECT_FALSE(m.duration_given);
  EXPECT_EQ(m.source.dataset, "mrclam/MRCLAM_Dataset7");
  EXPECT_EQ(ParseScenario("source: {type: mrclam}\n", "m.yaml", {}, 3).robots.size(), 3u);
  const Scenario v = ParseScenario(
      "source: {type: victoria_park}\nduration_s: 100\nrobots: {defaults: {motion: {model: ackermann}}}\n", "v.yaml",
      {}, 6);
  EXPECT_EQ(v.robots.size(), 6u);
  EXPECT_EQ(v.source.virtual_robots, 6);
  EXPECT_TRUE(v.duration_given);
  EXPECT_EQ(MotionModelFor(v.robots[0].motion).kind, MotionModel::Kind::kAckermann);
  EXPECT_NE(ErrorOf("source: {type: mrclam, robots: [7]}\n").find("source.robots[0]: MRCLAM has robots 1-5"),
            std::string::npos);
  EXPECT_NE(ErrorOf("source: {type: mrclam}\nworld: {landmarks: {list: [[0, 0]]}}\n")
                .find("takes its landmarks from the dataset"),
            std::string::npos);
  EXPECT_NE(ErrorOf("source: {type: mrclam}\nrobots: {count: 3}\n").find("robots.count: a dataset"), std::string::npos);
  EXPECT_NE(ErrorOf("source: {type: mars}\n").find("source.type: must be one of"), std::string::npos);
}

}  // namespace
}  // namespace mapmesh
