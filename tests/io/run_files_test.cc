#include "common/io/run_files.h"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cerrno>
#include <iterator>

#include <algorithm>
#include <filesystem>
#include <fstream>

namespace mapmesh::io {
namespace {

TEST(RunFiles, MapJsonRoundTrips) {
  LandmarkMap m;
  Eigen::Matrix2d c;
  c << 0.5, 0.1, 0.1, 0.2;
  m.landmarks.push_back({7, 3, {1.25, -2.5}, c});
  m.landmarks.push_back({9, -1, {0, 0}, Eigen::Matrix2d::Identity()});
  const LandmarkMap back = MapFromJson(MapToJson(m));
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back.landmarks[0].id, 7u);
  EXPECT_EQ(back.landmarks[0].signature, 3);
  EXPECT_EQ(back.landmarks[0].mean, m.landmarks[0].mean);
  EXPECT_EQ(back.landmarks[0].cov, c);
  EXPECT_THROW(MapFromJson(json{{"landmarks", {{{"x", 1}}}}}), std::runtime_error);
}

// A global landmark's origins name the source maps' landmarks; one from a relayed global map
// (a peer's global map, whose ids are its own and not its robot's) is marked, so that the
// evaluation does not read its id as its robot's landmark.
TEST(RunFiles, GlobalMapJsonMarksOriginsFromRelayedMaps) {
  const Eigen::Matrix2d c = 0.01 * Eigen::Matrix2d::Identity();
  LandmarkMap local, direct, relay;
  local.landmarks.push_back({1, 4, {0, 0}, c});
  direct.landmarks.push_back({5, -1, {0.01, 0}, c});
  relay.landmarks.push_back({70, -1, {0, 0.01}, c});
  relay.landmarks.push_back({71, -1, {20, 0}, c});
  const std::vector<MapSource> sources = {{2, 1, direct, Pose2{}, Eigen::Matrix3d::Zero(), false},
                                          {3, 1, relay, Pose2{}, Eigen::Matrix3d::Zero(), true}};
  const GlobalMap g = BuildGlobalMap(local, 1, sources, {}, 1);
  ASSERT_EQ(g.map.size(), 2u);
  const json j = GlobalMapToJson(g);
  EXPECT_TRUE(j.at("origins_mark_relays").get<bool>());
  ASSERT_EQ(j.at("landmarks").size(), 2u);
  std::vector<json> all;
  for (const json& l : j.at("landmarks")) {
    for (const json& o : l.at("origins")) all.push_back(o);
  }
  EXPECT_EQ(all.size(), 4u);
  EXPECT_NE(std::find(all.begin(), all.end(), json{1, 1, 1}), all.end());      // the own
  EXPECT_NE(std::find(all.begin(), all.end(), json{2, 1, 5}), all.end());      // a peer's local map
  EXPECT_NE(std::find(all.begin(), all.end(), json{3, 1, 70, 1}), all.end());  // relayed
  EXPECT_NE(std::find(all.begin(), all.end(), json{3, 1, 71, 1}), all.end());
}

TEST(RunFiles, TruthRoundTripsAndInterpolates) {
  RunTruth t;
  t.scenario = "s";
  t.duration_s = 2;
  t.landmarks = {{1, 2}, {3, 4}};
  t.seen = {1};
  RobotTruth r;
  r.id = 4;
  r.start = {0, 0, 0};
  r.trajectory = {{0.0, {0, 0, 3.0}}, {1.0, {2, 4, -3.0}}};
  t.robots.push_back(r);
  const RunTruth back = TruthFromJson(TruthToJson(t));
  ASSERT_NE(back.Find(4), nullptr);
  EXPECT_EQ(back.Find(5), nullptr);
  EXPECT_EQ(back.seen, std::vector<int>{1});
  const Pose2 mid = *back.Find(4)->PoseAt(0.5);
  EXPECT_NEAR(mid.x, 1.0, 1e-12);
  EXPECT_NEAR(mid.y, 2.0, 1e-12);
  // Heading interpolates the short way round, through pi.
  EXPECT_NEAR(std::abs(mid.theta), M_PI, 1e-9);
  EXPECT_NEAR(back.Find(4)->PoseAt(5.0)->x, 2.0, 1e-12);  // clamped
  EXPECT_NEAR(back.Find(4)->PoseAt(-1.0)->x, 0.0, 1e-12);
  EXPECT_TRUE(back.headings_known);
  // Unknown starts survive the round trip.
  t.robots[0].start.reset();
  t.robots[0].trajectory.clear();
  t.headings_known = false;
  const RunTruth unknown = TruthFromJson(TruthToJson(t));
  EXPECT_FALSE(unknown.Find(4)->start.has_value());
  EXPECT_FALSE(unknown.Find(4)->PoseAt(1.0).has_value());
  EXPECT_FALSE(unknown.headings_known);
}

TEST(RunFiles, AtomicWriteAndReadErrors) {
  const std::string dir = std::filesystem::temp_directory_path() / ("mapmesh_io_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  WriteJsonAtomic(dir + "/a.json", {{"k", 1}});
  EXPECT_FALSE(std::filesystem::exists(dir + "/a.json.tmp"));
  EXPECT_EQ(ReadJson(dir + "/a.json")["k"], 1);
  std::ofstream(dir + "/bad.json") << "{not json";
  try {
    ReadJson(dir + "/bad.json");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos);
  }
  EXPECT_THROW(ReadJson(dir + "/missing.json"), std::runtime_error);
  EXPECT_THROW(WriteJsonAtomic(dir + "/no/such/dir/x.json", {}), std::runtime_error);
  std::filesystem::remove_all(dir);
}

// A failed write says why (errno) and leaves nothing behind: the file keeps what it held and no
// temporary file stays. (A full file system is the integration test's: faults_test DiskFullTest.)
TEST(RunFiles, FailedWritesSayWhyAndLeaveNothingBehind) {
  const std::string dir = std::filesystem::temp_directory_path() / ("mapmesh_io_fail_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir + "/a_directory");
  try {
    WriteJsonAtomic(dir + "/no/such/dir/x.json", {});
    FAIL();
  } catch (const WriteError& e) {
    EXPECT_EQ(e.error(), ENOENT);
    EXPECT_NE(std::string(e.what()).find("x.json.tmp: No such file or directory"), std::string::npos) << e.what();
  }
  // The rename fails (a directory is in the way): the temporary file goes.
  try {
    WriteFileAtomic(dir + "/a_directory", "text");
    FAIL();
  } catch (const WriteError& e) {
    EXPECT_EQ(e.error(), EISDIR);
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/a_directory.tmp"));
  EXPECT_TRUE(std::filesystem::is_directory(dir + "/a_directory"));
  // A device that is always full: the write's own error.
  try {
    AppendLine("/dev/full", "one line");
    FAIL();
  } catch (const WriteError& e) {
    EXPECT_EQ(e.error(), ENOSPC);
    EXPECT_EQ(std::string(e.what()), "/dev/full: No space left on device");
  }
  AppendLine(dir + "/h.jsonl", "1");
  AppendLine(dir + "/h.jsonl", "2");
  std::ifstream in(dir + "/h.jsonl");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text, "1\n2\n");
  std::filesystem::remove_all(dir);
}

// run.json's `resolved`: numbers stay numbers (to the last digit), lists of numbers lists, any
// other node read whole its YAML text.
TEST(RunFiles, ResolvedScenarioAsJsonKeepsTypes) {
  using K = ResolvedValue::Kind;
  const ResolvedScenario r = {{"a.n", {K::kNumber, "0.1"}},  {"a.big", {K::kNumber, "18446744073709551615"}},
                              {"b", {K::kBool, "false"}},    {"c", {K::kString, "lockstep"}},
                              {"d", {K::kYaml, "[1, 2.5]"}}, {"e", {K::kYaml, "{x: 1}"}}};
  const json j = ResolvedToJson(r);
  EXPECT_EQ(j.at("a.n").get<double>(), 0.1);
  EXPECT_EQ(j.at("a.big").get<std::uint64_t>(), 18446744073709551615ull);
  EXPECT_EQ(j.at("b"), false);
  EXPECT_EQ(j.at("c"), "lockstep");
  EXPECT_EQ(j.at("d"), json::parse("[1, 2.5]"));
  EXPECT_EQ(j.at("e"), "{x: 1}");
  EXPECT_EQ(j.size(), r.size());
}

}  // namespace
}  // namespace mapmesh::io
