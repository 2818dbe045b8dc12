#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "sim_feeder/dataset_table.h"
#include "sim_feeder/mrclam.h"
#include "sim_feeder/sources.h"
#include "sim_feeder/victoria_park.h"

namespace mapmesh {
namespace {

namespace fs = std::filesystem;

// The datasets root CI has beside the checkout (or $MAPMESH_DATASETS).
std::string DatasetsRoot() { return ResolveDatasetsRoot("", MAPMESH_SOURCE_DIR "/../shared/datasets"); }

#define SKIP_WITHOUT(dir)     \
  if (!fs::is_directory(dir)) \
  GTEST_SKIP() << "dataset not found at " << (dir) << " (set MAPMESH_DATASETS to run this test)"

TEST(ParseRow, RealLinesWithTabsSpacesAndTrailingSpace) {
  std::vector<double> v;
  // Robot3_Measurement.dat of MRCLAM dataset 7, line 5 (tabs between padded columns).
  ASSERT_TRUE(ParseRow("1248446192.940 \t  63 \t  5.414 \t -0.487", 4, v));
  EXPECT_DOUBLE_EQ(v[0], 1248446192.940);
  EXPECT_DOUBLE_EQ(v[1], 63);
  EXPECT_DOUBLE_EQ(v[3], -0.487);
  // Landmark_Groundtruth.dat of dataset 1, line 5 (a trailing space).
  ASSERT_TRUE(ParseRow("  6 \t 5.70928255 \t 4.96404466 \t 0.00027464 \t 0.00041465 ", 5, v));
  EXPECT_DOUBLE_EQ(v[2], 4.96404466);
  // Victoria Park measurements.dat line 1 (spaces only).
  ASSERT_TRUE(ParseRow("     0.852   20.46202    0.88575    0.35404", 4, v));
  EXPECT_DOUBLE_EQ(v[1], 20.46202);
  // Windows line end.
  ASSERT_TRUE(ParseRow("1 2 3\r", 3, v));
  EXPECT_FALSE(ParseRow("1 2", 3, v));
  EXPECT_FALSE(ParseRow("1 2 3 4", 3, v));
  EXPECT_FALSE(ParseRow("1 two 3", 3, v));
  EXPECT_FALSE(ParseRow("1 2x 3", 3, v));
  EXPECT_FALSE(ParseRow("1 nan 3", 3, v));
}

class TableFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mapmesh_table_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
    return (dir_ / name).string();
  }
  fs::path dir_;
};

TEST_F(TableFileTest, SkipsHeadersAndNamesTheBadLine) {
  const std::string ok = Write("ok.dat", "# header\n# more\n1.0 \t 2\n\n3 4 \n");
  const auto rows = ReadTable(ok, 2);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[1].line, 5);
  const std::string bad = Write("bad.dat", "# header\n1 2\n3 oops\n");
  try {
    ReadTable(bad, 2);
    FAIL();
  } catch (const DatasetError& e) {
    EXPECT_NE(std::string(e.what()).find(bad + ":3: expected 2 numbers, got '3 oops'"), std::string::npos) << e.what();
  }
  try {
    ReadTable((dir_ / "none.dat").string(), 2);
    FAIL();
  } catch (const DatasetError& e) {
    EXPECT_NE(std::string(e.what()).find("none.dat: cannot open"), std::string::npos);
  }
}

TEST_F(TableFileTest, MalformedMrclamFileIsOneLineNotACrash) {
  const fs::path d = dir_ / "MRCLAM_DatasetX";
  fs::create_directories(d);
  std::ofstream(d / "Barcodes.dat") << "# a\n1 5\n6 63\n";
  std::ofstream(d / "Landmark_Groundtruth.dat") << "6 1.0 2.0 0.1 0.1\n";
  std::ofstream(d / "Robot1_Odometry.dat") << "100.0 0.1 0.0\n100.5 0.1\n";
  std::ofstream(d / "Robot1_Measurement.dat") << "100.2 63 2.0 0.1\n";
  const Scenario sc = ParseScenario("source: {type: mrclam, robots: [1]}\n", "t.yaml");
  try {
    LoadMrclam(d.string(), sc);
    FAIL();
  } catch (const DatasetError& e) {
    EXPECT_NE(std::string(e.what()).find("Robot1_Odometry.dat:2: expected 3 numbers"), std::string::npos) << e.what();
  }
}

TEST(Datasets, MissingDirectoryIsOneClearLine) {
  Scenario m = ParseScenario("source: {type: mrclam, dataset: nowhere}\n", "t.yaml");
  try {
    MakeFeed(m, "/nonexistent/datasets");
    FAIL();
  } catch (const DatasetError& e) {
    EXPECT_EQ(
        std::string(e.what()),
        "/nonexistent/datasets/nowhere: MRCLAM dataset directory not found (set MAPMESH_DATASETS, or mapmesh-feeder --datasets)");
  }
  Scenario v = ParseScenario("source: {type: victoria_park}\n", "t.yaml");
  EXPECT_THROW(MakeFeed(v, "/nonexistent/datasets"), DatasetError);
}

TEST(Mrclam, Dataset7StreamsMatchTheFiles) {
  const std::string dir = DatasetsRoot() + "/mrclam/MRCLAM_Dataset7";
  SKIP_WITHOUT(dir);
  const Scenario sc = ParseScenario("source: {type: mrclam}\nrobots: {defaults: {sensor: {signatures: true}}}\n",
                                    "t.yaml");
  const ReplayData d = LoadMrclam(dir, sc);
  ASSERT_EQ(d.robots.size(), 5u);
  ASSERT_EQ(d.landmarks.size(), 15u);
  EXPECT_NEAR(d.landmarks[0].x(), 0.58842660, 1e-9);  // subject 6
  EXPECT_EQ(std::count(d.seen.begin(), d.seen.end(), true), 15);
  EXPECT_NEAR(d.duration_s, 893.8, 0.5);
  // Robot 2: 60936 odometry rows, 4 repeating their timestamp (merged).
  const ReplayCounts& c2 = d.counts[1];
  EXPECT_EQ(c2.odom_rows, 60936);
  EXPECT_EQ(c2.odom_duplicate_rows, 4);
  EXPECT_EQ(d.robots[1].odom.size(), 60936u - 4u);
  // Robot 3: 9 measurements of unknown barcodes dropped.
  EXPECT_EQ(d.counts[2].measurement_unknown, 9);
  for (std::size_t i = 0; i < d.robots.size(); ++i) {
    const RobotStreams& r = d.robots[i];
    SCOPED_TRACE(r.id);
    std::size_t obs = 0, announced = 0;
    for (const Scan& s : r.scans) obs += s.obs.size();
    EXPECT_EQ(static_cast<int>(obs), d.counts[i].measurement_rows - d.counts[i].measurement_unknown);
    for (std::size_t k = 0; k < r.odom.size(); ++k) {
      announced += r.odom[k].scans_in_interval;
      ASSERT_EQ(r.odom[k].seq, k);
      ASSERT_GT(r.odom[k].dt, 0.0);
      if (k > 0) {
        ASSERT_NEAR(r.odom[k].stamp - r.odom[k].dt, r.odom[k - 1].stamp, 1e-9);
      }
    }
    EXPECT_EQ(announced, r.scans.size());  // every scan falls in exactly one interval
    EXPECT_GE(r.odom.front().stamp - r.odom.front().dt, -1e-9);
    ASSERT_TRUE(r.start.has_value());
    EXPECT_FALSE(r.truth.empty());
  }
  // Robot sightings carry the seen robot's id.
  int sightings = 0;
  for (const Scan& s : d.robots[0].scans) {
    for (const Observation& o : s.obs) {
      if (o.kind == ObservationKind::kRobot) {
        ++sightings;
        EXPECT_GE(o.signature, 2);
        EXPECT_LE(o.signature, 5);
      }
    }
  }
  EXPECT_EQ(sightings, d.counts[0].robot_sightings);
}

TEST(Mrclam, SignaturesOnlyWhenShared) {
  const std::string dir = DatasetsRoot() + "/mrclam/MRCLAM_Dataset1";
  SKIP_WITHOUT(dir);
  const ReplayData d = LoadMrclam(dir, ParseScenario("source: {type: mrclam, robots: [1]}\n", "t.yaml"));
  EXPECT_FALSE(d.robots[0].start.has_value());  // dataset 1 ships no robot ground truth
  for (const Scan& s : d.robots[0].scans) {
    for (const Observation& o : s.obs) {
      if (o.kind == ObservationKind::kLandmark) {
        ASSERT_EQ(o.signature, -1);
      }
    }
  }
}

TEST(VictoriaPark, VirtualRobotsShareTheRunWithOverlap) {
  const std::string dir = DatasetsRoot() + "/victoria_park";
  SKIP_WITHOUT(dir);
  const Scenario sc = ParseScenario(
      "source: {type: victoria_park, overlap_s: 60}\nrobots: {defaults: {motion: {model: ackermann}}}\n", "t.yaml", {},
      4);
  const ReplayData d = LoadVictoriaPark(dir, sc);
  ASSERT_EQ(d.robots.size(), 4u);
  EXPECT_FALSE(d.headings_known);
  int odom = 0, meas = 0;
  for (std::size_t i = 0; i < 4; ++i) {
    const RobotStreams& r = d.robots[i];
    odom += static_cast<int>(r.odom.size());
    for (const Scan& s : r.scans) {
      meas += static_cast<int>(s.obs.size());
      for (const Observation& o : s.obs) {
        ASSERT_GE(o.bearing, -M_PI / 2 - 1e-9);  // laser 0..pi turned to -pi/2..pi/2
        ASSERT_LE(o.bearing, M_PI / 2 + 1e-9);
        ASSERT_EQ(o.signature, -1);
      }
    }
    EXPECT_NEAR(r.odom.front().stamp - r.odom.front().dt, 0.0, 1e-9);
    EXPECT_FALSE(r.truth.empty());
    EXPECT_NEAR(r.odom.back().stamp, d.duration_s, 1.0);
  }
  // (61945 rows + 3 overlaps of ~60 s at 40 Hz) and (52974 detections + overlaps).
  EXPECT_GT(odom, 61945);
  EXPECT_LT(odom, 61945 + 3 * 61 * 41);
  EXPECT_GT(meas, 52974);
}

}  // namespace
}  // namespace mapmesh
