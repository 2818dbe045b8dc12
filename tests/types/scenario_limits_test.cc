// Scenario loading's bounds (common/types/scenario_limits.h) and its checks of keys and files:
// each bad case fails with one line naming the file, the line (or --set) and the key.

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "common/config/config_error.h"
#include "common/config/scenario.h"
#include "common/types/scenario_limits.h"
#include "tests/config/scenario_testing.h"

namespace mapmesh {
namespace {

namespace fs = std::filesystem;

using testing::ErrorOf;
using testing::kSimulation;
constexpr const char* kDiscWorld = "world: {landmarks: {generator: {type: disc, count: 10}}}\nrobots: {count: 1}\n";
constexpr const char* kMrclam = "source: {type: mrclam}\n";
constexpr const char* kVictoria = "source: {type: victoria_park}\nrobots: {defaults: {motion: {model: ackermann}}}\n";

// One bound: with `setup` applied, key=ok (the bound itself) loads and key=bad fails with
// "s.yaml: --set key: reason".
struct Bound {
  const char* base;
  std::vector<std::string> setup;
  std::string key, ok, bad, reason;
};

void PrintTo(const Bound& b, std::ostream* os) { *os << b.key << "=" << b.bad; }

class BoundTest : public ::testing::TestWithParam<Bound> {};

TEST_P(BoundTest, TheBoundLoadsAndBeyondItIsOneLineNamingTheKey) {
  const Bound& b = GetParam();
  std::vector<std::string> sets = b.setup;
  sets.push_back(b.key + "=" + b.ok);
  EXPECT_EQ(ErrorOf(b.base, sets), "");
  sets.back() = b.key + "=" + b.bad;
  EXPECT_EQ(ErrorOf(b.base, sets), "s.yaml: --set " + b.key + ": " + b.reason);
}

const std::vector<std::string> kPark = {"world.landmarks.generator.type=park"};
const std::vector<std::string> kCircle = {"robots.defaults.path.type=circle"};
const std::vector<std::string> kLawnmower = {"robots.defaults.path.type=lawnmower"};
const std::vector<std::string> kParkPath = {"world.landmarks.generator.type=park", "robots.defaults.path.type=park"};
const std::vector<std::string> kNoSpacing = {"world.landmarks.generator.min_spacing_m=0"};
const std::vector<std::string> kNoLandmarks = {"world.landmarks.generator.count=0"};

// One bound per line: a table (not formatted).
// clang-format off
INSTANTIATE_TEST_SUITE_P(
    EveryKey, BoundTest,
    ::testing::Values(
        Bound{kSimulation, {}, "duration_s", "1e6", "1000001", "must be <= 1000000 (got 1000001)"},
        Bound{kSimulation, {}, "duration_s", "1e-9", "0", "must be > 0 (got 0)"},
        Bound{kMrclam, {}, "duration_s", "1e6", "1e300", "must be <= 1000000 (got 1e+300)"},
        Bound{kMrclam, {}, "source.odometry_delay_s", "5", "5.5", "must be <= 5 (got 5.5)"},
        Bound{kVictoria, {}, "source.virtual_robots", "1024", "1025", "must be <= 1024 (got 1025)"},
        Bound{kVictoria, {}, "source.virtual_robots", "1", "0", "must be >= 1 (got 0)"},
        Bound{kVictoria, {}, "source.overlap_s", "1e6", "1.5e6", "must be <= 1000000 (got 1500000)"},
        Bound{kSimulation, {}, "world.control_period_s", "10", "10.5", "must be <= 10 (got 10.5)"},
        Bound{kSimulation, {}, "world.control_period_s", "0.001", "0.0009", "must be >= 0.001 (got 0.0009)"},
        Bound{kSimulation, kNoSpacing, "world.landmarks.generator.count", "100000", "100001",
              "must be <= 100000 (got 100001)"},
        Bound{kSimulation, kNoLandmarks, "world.landmarks.generator.min_spacing_m", "1e5", "100001",
              "must be <= 100000 (got 100001)"},
        Bound{kSimulation, {}, "world.landmarks.generator.area_m", "[-1e5, -1e5, 1e5, 1e5]", "[0, 0, 100001, 5]",
              "coordinates must be within +-100000 m (got 100001)"},
        Bound{kSimulation, {}, "world.bounds_m", "[-1e5, -1e5, 1e5, 1e5]", "[-100001, 0, 5, 5]",
              "coordinates must be within +-100000 m (got -100001)"},
        Bound{kSimulation, kPark, "world.landmarks.generator.paths", "20", "21", "must be <= 20 (got 21)"},
        Bound{kSimulation, kPark, "world.landmarks.generator.path_width_m", "1e5", "1e6", "must be <= 100000 (got 1000000)"},
        Bound{kSimulation, kPark, "world.landmarks.generator.scatter_fraction", "1", "1.5", "must be <= 1 (got 1.5)"},
        Bound{kDiscWorld, {}, "world.landmarks.generator.center_m", "[1e5, -1e5]", "[0, 2e5]",
              "coordinates must be within +-100000 m (got 200000)"},
        Bound{kDiscWorld, {}, "world.landmarks.generator.radius_m", "1e5", "100001", "must be <= 100000 (got 100001)"},
        Bound{kSimulation, {}, "robots.count", "1024", "1025", "must be <= 1024 (got 1025)"},
        Bound{kSimulation, {}, "robots.defaults.motion.speed_mps", "100", "101", "must be <= 100 (got 101)"},
        Bound{kSimulation, {}, "robots.defaults.motion.max_turn_rate_dps", "3600", "3601", "must be <= 3600 (got 3601)"},
        Bound{kSimulation, {}, "robots.defaults.motion.max_turn_rate_dps", "0.1", "0", "must be > 0 (got 0)"},
        Bound{kSimulation, {}, "robots.defaults.motion.sigma_v_mps", "10", "10.5", "must be <= 10 (got 10.5)"},
        Bound{kSimulation, {}, "robots.defaults.motion.sigma_w_radps", "10", "1e300", "must be <= 10 (got 1e+300)"},
        Bound{kSimulation, {}, "robots.defaults.motion.sigma_steering_rad", "1", "1.5", "must be <= 1 (got 1.5)"},
        Bound{kSimulation, {}, "robots.defaults.motion.sigma_steering_rad", "0", "-0.1", "must be >= 0 (got -0.1)"},
        Bound{kSimulation, {}, "robots.defaults.motion.waypoint_radius_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "robots.defaults.motion.ackermann.wheelbase_m", "100", "101", "must be <= 100 (got 101)"},
        Bound{kSimulation, {}, "robots.defaults.motion.ackermann.encoder_offset_m", "100", "101", "must be <= 100 (got 101)"},
        Bound{kSimulation, {}, "robots.defaults.motion.ackermann.laser_a_m", "-100", "-101", "must be >= -100 (got -101)"},
        Bound{kSimulation, {}, "robots.defaults.motion.ackermann.laser_b_m", "100", "101", "must be <= 100 (got 101)"},
        Bound{kSimulation, {}, "robots.defaults.sensor.max_range_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "robots.defaults.sensor.fov_deg", "360", "361", "must be <= 360 (got 361)"},
        Bound{kSimulation, {}, "robots.defaults.sensor.fov_deg", "0.001", "0", "must be > 0 (got 0)"},
        Bound{kSimulation, {}, "robots.defaults.sensor.sigma_range_m", "100", "1e300", "must be <= 100 (got 1e+300)"},
        Bound{kSimulation, {}, "robots.defaults.sensor.sigma_bearing_deg", "180", "181", "must be <= 180 (got 181)"},
        Bound{kSimulation, {}, "robots.defaults.sensor.scan_every_steps", "100000", "100001",
              "must be <= 100000 (got 100001)"},
        Bound{kSimulation, {}, "robots.defaults.sensor.scan_every_steps", "1", "0", "must be >= 1 (got 0)"},
        Bound{kSimulation, {}, "robots.defaults.path.count", "10000", "10001", "must be <= 10000 (got 10001)"},
        Bound{kSimulation, {}, "robots.defaults.path.area_m", "[0, 0, 1e5, 1]", "[0, 0, 1, 1e6]",
              "coordinates must be within +-100000 m (got 1000000)"},
        Bound{kSimulation, kCircle, "robots.defaults.path.center_m", "[-1e5, 0]", "[-2e5, 0]",
              "coordinates must be within +-100000 m (got -200000)"},
        Bound{kSimulation, kCircle, "robots.defaults.path.radius_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, kCircle, "robots.defaults.path.start_angle_deg", "-360", "-361", "must be >= -360 (got -361)"},
        Bound{kSimulation, kLawnmower, "robots.defaults.path.spacing_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        // 50 m of world bounds: 4951 lanes of two waypoints at 0.0101 m, 5051 at 0.0099 m.
        Bound{kSimulation, kLawnmower, "robots.defaults.path.spacing_m", "0.0101", "0.0099",
              "a lawnmower with lanes spacing_m apart over its area has 10102 waypoints (at most 10000)"},
        Bound{kSimulation, kParkPath, "robots.defaults.path.index", "1023", "1024", "must be <= 1023 (got 1024)"},
        Bound{kSimulation, {}, "radio.range_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "radio.loss_probability", "1", "1.01", "must be <= 1 (got 1.01)"},
        Bound{kSimulation, {}, "radio.bandwidth_bytes_per_s", "1e12", "2e12", "must be <= 1000000000000 (got 2000000000000)"},
        Bound{kSimulation, {}, "radio.latency_s", "3600", "3601", "must be <= 3600 (got 3601)"},
        Bound{kSimulation, {}, "radio.latency_s", "0", "-0.5", "must be >= 0 (got -0.5)"},
        Bound{kSimulation, {}, "radio.latency_jitter_s", "3600", "3601", "must be <= 3600 (got 3601)"},
        Bound{kSimulation, {}, "radio.links_period_s", "0.001", "1e-300", "must be >= 0.001 (got 1e-300)"},
        Bound{kSimulation, {}, "radio.links_period_s", "1e6", "2e6", "must be <= 1000000 (got 2000000)"},
        Bound{kSimulation, {}, "agent.gate_probability", "0.999999", "1", "must be <= 0.999999 (got 1)"},
        Bound{kSimulation, {}, "agent.new_landmark_chi2", "1000", "1001", "must be <= 1000 (got 1001)"},
        Bound{kSimulation, {}, "agent.tentative_gate_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "agent.tentative_timeout_s", "1e6", "2e6", "must be <= 1000000 (got 2000000)"},
        Bound{kSimulation, {}, "agent.min_range_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "agent.max_range_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "agent.region_half_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "agent.region_reach_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "agent.map_publish_period_s", "0.001", "0.0001", "must be >= 0.001 (got 0.0001)"},
        Bound{kSimulation, {}, "agent.status_period_s", "1e6", "2e6", "must be <= 1000000 (got 2000000)"},
        Bound{kSimulation, {}, "agent.association_gate_m", "1e5", "2e5", "must be <= 100000 (got 200000)"},
        Bound{kSimulation, {}, "agent.align_period_s", "0.001", "0", "must be >= 0.001 (got 0)"},
        Bound{kSimulation, {}, "agent.refine_period_s", "0", "0.0005", "must be 0 (off) or >= 0.001 (got 0.0005)"},
        Bound{kSimulation, {}, "agent.refine_period_s", "1e6", "2e6", "must be <= 1000000 (got 2000000)"},
        Bound{kSimulation, {}, "agent.drop_after_failures", "1000", "1001", "must be <= 1000 (got 1001)"},
        Bound{kSimulation, {}, "agent.checkpoint_period_s", "0", "-1", "must be >= 0 (got -1)"},
        Bound{kSimulation, {}, "agent.checkpoint_period_s", "1e6", "2e6", "must be <= 1000000 (got 2000000)"},
        Bound{kSimulation, {}, "feeder.realtime_factor", "1e4", "2e4", "must be <= 10000 (got 20000)"},
        Bound{kSimulation, {}, "feeder.realtime_factor", "0.001", "1e-300", "must be >= 0.001 (got 1e-300)"},
        Bound{kSimulation, {}, "feeder.lockstep_window_s", "10", "11", "must be <= 10 (got 11)"},
        Bound{kSimulation, {}, "feeder.startup_timeout_s", "86400", "1e300", "must be <= 86400 (got 1e+300)"},
        Bound{kSimulation, {}, "feeder.truth_period_s", "0.001", "0.0009", "must be >= 0.001 (got 0.0009)"}));
// clang-format on

// The user's reports: each is one line with file, line and key.
TEST(ScenarioLimits, HugeLandmarkCountWithATinySpacingIsRefusedAtItsLine) {
  EXPECT_EQ(ErrorOf("version: 1\nworld:\n  landmarks:\n    generator: {count: 1000000, min_spacing_m: 1e-300}\n"
                    "robots: {count: 1}\n"),
            "s.yaml:4: world.landmarks.generator.count: must be <= 100000 (got 1000000)");
}

TEST(ScenarioLimits, IntegersWrittenAsFloatsOrTooLargeAreRefused) {
  EXPECT_EQ(ErrorOf("world:\n  landmarks:\n    generator: {count: 1e9}\nrobots: {count: 1}\n"),
            "s.yaml:3: world.landmarks.generator.count: expected an integer, got '1e9'");
  EXPECT_EQ(ErrorOf("world: {landmarks: {generator: {count: 5}}}\nrobots:\n  count: 1\n  defaults:\n"
                    "    path: {count: 2e9}\n"),
            "s.yaml:5: robots.defaults.path.count: expected an integer, got '2e9'");
  EXPECT_EQ(ErrorOf("world: {landmarks: {generator: {count: 5}}}\nrobots:\n  count: 1\n  defaults:\n"
                    "    path: {count: 2000000000}\n"),
            "s.yaml:5: robots.defaults.path.count: must be <= 10000 (got 2000000000)");
  // Beyond int: not an integer this build reads.
  EXPECT_EQ(ErrorOf("world: {landmarks: {generator: {count: 5}}}\nrobots: {count: 3000000000}\n"),
            "s.yaml:2: robots.count: expected an integer, got '3000000000'");
}

TEST(ScenarioLimits, DurationAndNoiseBeyondTheirBoundsAreRefusedAtTheirLines) {
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "duration_s: 1e300\n"),
            "s.yaml:7: duration_s: must be <= 1000000 (got 1e+300)");
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "  defaults:\n    sensor: {sigma_range_m: 1e300}\n"),
            "s.yaml:8: robots.defaults.sensor.sigma_range_m: must be <= 100 (got 1e+300)");
}

TEST(ScenarioLimits, RunsOfMoreThanTenMillionStepsAreRefused) {
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "duration_s: 1e6\n"), "");  // 10^7 steps of 0.1 s
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "duration_s: 1e6\n", {"world.control_period_s=0.05"}),
            "s.yaml:7: duration_s: the run would take 20000000 steps of world.control_period_s (at most 10000000)");
  // Datasets replay their own odometry: the step count does not apply.
  EXPECT_EQ(ErrorOf(std::string(kMrclam) + "duration_s: 1e6\nworld: {control_period_s: 0.001}\n"), "");
}

TEST(ScenarioLimits, RobotCountsAndIds) {
  EXPECT_EQ(ErrorOf(kSimulation, {}, 1024), "");
  EXPECT_EQ(ErrorOf(kSimulation, {}, 1025), "s.yaml: --agents 1025: must be in [0, 1024] (0: the scenario's robots)");
  EXPECT_EQ(ErrorOf(kVictoria, {}, 1025), "s.yaml: --agents 1025: must be in [0, 1024] (0: the scenario's robots)");
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "  list: [{id: 1000000}]\n"), "");
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "  list: [{id: 1000001}]\n"),
            "s.yaml:7: robots.list[0].id: must be <= 1000000 (got 1000001)");
  std::string many = "world: {landmarks: {generator: {count: 5}}}\nrobots:\n  list:\n";
  for (int i = 1; i <= limits::kMaxRobots + 1; ++i) many += "    - {id: " + std::to_string(i) + "}\n";
  EXPECT_EQ(ErrorOf(many), "s.yaml:4: robots.list: at most 1024 entries (got 1025)");
  EXPECT_EQ(ErrorOf("source: {type: mrclam, robots: [1, 3, 1]}\n"),
            "s.yaml:1: source.robots[2]: robot 1 is listed twice");
}

TEST(ScenarioLimits, StartPosesAndInlinePoints) {
  const std::string base = "world: {landmarks: {list: [[0, 0]]}}\nrobots:\n  list:\n";
  EXPECT_EQ(ErrorOf(base + "    - {id: 1, start: [1e5, -1e5, -360]}\n"), "");
  EXPECT_EQ(ErrorOf(base + "    - {id: 1, start: [0, 0, 361]}\n"),
            "s.yaml:4: robots.list[0].start: the heading must be within +-360 degrees (got 361)");
  EXPECT_EQ(ErrorOf(base + "    - {id: 1, start: [0, 2e5, 0]}\n"),
            "s.yaml:4: robots.list[0].start: coordinates must be within +-100000 m (got 200000)");
  EXPECT_EQ(ErrorOf(base + "    - {id: 1, path: {type: waypoints, points: [[0, 0], [1e300, 0]]}}\n"),
            "s.yaml:4: robots.list[0].path.points[1]: coordinates must be within +-100000 m");
  EXPECT_EQ(ErrorOf("world: {landmarks: {list: [[0, 0], [0, -100001]]}}\nrobots: {count: 1}\n"),
            "s.yaml:1: world.landmarks.list[1]: coordinates must be within +-100000 m");
  std::string points = "[[0, 0]";
  for (int i = 1; i <= limits::kMaxWaypoints; ++i) points += ", [" + std::to_string(i % 100) + ", 0]";
  EXPECT_EQ(ErrorOf(base + "    - {id: 1, path: {type: waypoints, points: " + points + "]}}\n"),
            "s.yaml:4: robots.list[0].path.points: at most 10000 points (got 10001)");
}

// Every process loads every robot's path, so all robots' waypoints together are bounded too.
TEST(ScenarioLimits, AllRobotsWaypointsTogetherAreBounded) {
  const std::string world = "version: 1\nworld: {landmarks: {list: [[0, 0], [3, 4]]}}\n";
  // A lawnmower over 100 m with lanes 0.0201 m apart: 4976 lanes, 9952 waypoints per robot.
  const std::string robots = "robots:\n  count: 1024\n  defaults:\n    path: {type: lawnmower, "
                             "area_m: [0, 0, 100, 100], spacing_m: 0.0201}\n";
  EXPECT_EQ(ErrorOf(world + robots),
            "s.yaml:4: robots.count: the first 101 of the run's 1024 robots already have 1005152 path "
            "waypoints (at most 1000000 in all: fewer robots or shorter paths)");
  // 100 such robots are 995200 waypoints: within the bound.
  EXPECT_EQ(ErrorOf(world + robots, {"robots.count=100"}), "");
  // With --agents the key is still robots.count (the robots come from there).
  EXPECT_EQ(ErrorOf(world + robots, {}, 200).substr(0, 22), "s.yaml:4: robots.count");
}

TEST(ScenarioLimits, AnEmptyOverrideIsAnError) {
  try {
    ParseOverride("duration_s=");
    ADD_FAILURE() << "accepted an empty value";
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(), "--set duration_s: empty value (give key.path=VALUE)");
  }
  EXPECT_THROW(ParseOverride("radio.range_m=  "), ConfigError);
  // A YAML null would also leave the key at its default.
  EXPECT_EQ(ErrorOf(kSimulation, {"duration_s=~"}), "s.yaml: --set duration_s: empty value (give key.path=VALUE)");
  EXPECT_EQ(ErrorOf(kSimulation, {"radio.range_m=null"}),
            "s.yaml: --set radio.range_m: empty value (give key.path=VALUE)");
  EXPECT_EQ(ErrorOf(kSimulation, {"name=''"}), "");  // an empty string, said so
}

class ScenarioFilesTest : public testing::TempDirTest {
 protected:
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  // Loads a scenario whose landmarks come from csv (relative to the scenario's folder).
  std::string CsvError(const std::string& csv) {
    const std::string path = Path("s.yaml");
    std::ofstream(path) << "version: 1\nworld:\n  landmarks:\n    csv: '" << csv << "'\nrobots: {count: 1}\n";
    try {
      LoadScenario(path);
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  }
};

TEST_F(ScenarioFilesTest, TheLandmarksCsvMustBeARegularFileWithLandmarks) {
  const std::string prefix = Path("s.yaml") + ":4: world.landmarks.csv: ";
  fs::create_directories(dir_ / "folder");
  EXPECT_EQ(CsvError("folder"), prefix + "cannot open landmarks file '" + Path("folder") + "': it is a directory");
  EXPECT_EQ(CsvError(""), prefix + "cannot open landmarks file '" + dir_.string() + "/': it is a directory");
  ASSERT_EQ(::mkfifo(Path("fifo").c_str(), 0600), 0);  // reading it would block for ever
  EXPECT_EQ(CsvError("fifo"), prefix + "cannot open landmarks file '" + Path("fifo") + "': not a regular file");
  std::ofstream(Path("empty.csv")).close();
  EXPECT_EQ(CsvError("empty.csv"), prefix + "landmarks file '" + Path("empty.csv") + "' holds no landmarks");
  std::ofstream(Path("header.csv")) << "x,y\n# nothing yet\n";
  EXPECT_EQ(CsvError("header.csv"), prefix + "landmarks file '" + Path("header.csv") + "' holds no landmarks");
  std::ofstream(Path("far.csv")) << "x,y\n1,2\n3,1e300\n";
  EXPECT_EQ(CsvError("far.csv"), prefix + Path("far.csv") + ":3: coordinates must be within +-100000 m");
  {
    std::ofstream many(Path("many.csv"));
    for (int i = 0; i <= limits::kMaxLandmarks; ++i) many << i % 1000 << "," << i / 1000 << "\n";
  }
  EXPECT_EQ(CsvError("many.csv"), prefix + Path("many.csv") + ":100001: more than 100000 landmarks");
  fs::resize_file(Path("many.csv"), limits::kMaxCsvBytes + 1);
  EXPECT_EQ(CsvError("many.csv"),
            prefix + "cannot open landmarks file '" + Path("many.csv") + "': larger than 64 MiB (67108865 bytes)");
}

TEST_F(ScenarioFilesTest, TheScenarioMustBeARegularFile) {
  try {
    LoadScenario(dir_.string());
    ADD_FAILURE() << "loaded a directory";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), dir_.string() + ": cannot open scenario file: it is a directory");
  }
  EXPECT_THROW(LoadScenario(Path("missing.yaml")), ConfigError);
}

// The file's values are counted before the document is built: the limit itself loads (here an
// inline landmark list of exactly kMaxScenarioValues values in all), one more is refused at its
// line, whatever the rest of the file holds.
TEST(ScenarioLimits, ValuesBeyondTheLimitAreRefusedBeforeTheDocumentIsBuilt) {
  // Keys are values too. The head: the top map, robots, its map, count, 1, world, its map,
  // landmarks, its map, list and its list: 11 values on 4 lines.
  const std::string head = "robots: {count: 1}\nworld:\n  landmarks:\n    list:\n";
  const std::size_t head_values = 11;
  // Each point is 3 values (a list and two numbers) on a line; each "kN: 1" after it is 2.
  const std::size_t points = (limits::kMaxScenarioValues - head_values) / 3;
  const std::size_t spare = limits::kMaxScenarioValues - head_values - 3 * points;
  ASSERT_EQ(spare % 2, 0u);
  std::string at_limit = head;
  for (std::size_t i = 0; i < points; ++i) at_limit += "      - [" + std::to_string(i % 50) + ", 1]\n";
  for (std::size_t i = 0; i < spare / 2; ++i) at_limit += "k" + std::to_string(i) + ": 1\n";
  EXPECT_EQ(ErrorOf(at_limit).find("values in the file"), std::string::npos) << ErrorOf(at_limit);
  const std::string line = std::to_string(4 + points + spare / 2 + 1);
  EXPECT_EQ(ErrorOf(at_limit + "one_more: 1\n"),
            "s.yaml:" + line + ": (top level): more than " + std::to_string(limits::kMaxScenarioValues) +
                " values in the file (a scenario holds hundreds; a large landmark map goes in world.landmarks.csv)");
}

}  // namespace
}  // namespace mapmesh
