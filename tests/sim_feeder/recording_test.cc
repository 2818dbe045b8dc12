#include "sim_feeder/recording.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "sim_feeder/simulator.h"

namespace mapmesh {
namespace {

namespace fs = std::filesystem;

TEST(Recording, RoundTripsEveryField) {
  const std::string path = fs::temp_directory_path() / ("mapmesh_rec_" + std::to_string(::getpid()) + ".bin");
  const Scenario sc = ParseScenario(R"(duration_s: 3
world: {landmarks: {generator: {count: 40, area_m: [0, 0, 20, 20]}}}
robots: {count: 2, defaults: {sensor: {signatures: true}}}
radio: {range_m: 15}
)",
                                    "r.yaml");
  Simulator sim(sc, BuildWorld(sc));
  std::vector<FeedBatch> batches;
  {
    RecordingWriter w(path);
    while (!sim.Done()) {
      batches.push_back(sim.Next());
      w.Write(batches.back());
    }
    w.Close();
  }
  const std::vector<FeedBatch> back = ReadRecording(path);
  ASSERT_EQ(back.size(), batches.size());
  std::size_t obs = 0;
  for (std::size_t i = 0; i < batches.size(); ++i) {
    const FeedBatch &a = batches[i], &b = back[i];
    ASSERT_EQ(a.stamp, b.stamp);
    ASSERT_EQ(a.odom.size(), b.odom.size());
    for (std::size_t k = 0; k < a.odom.size(); ++k) {
      EXPECT_EQ(a.odom[k].v, b.odom[k].v);
      EXPECT_EQ(a.odom[k].seq, b.odom[k].seq);
      EXPECT_EQ(a.odom[k].scans_in_interval, b.odom[k].scans_in_interval);
    }
    ASSERT_EQ(a.scans.size(), b.scans.size());
    for (std::size_t k = 0; k < a.scans.size(); ++k) {
      ASSERT_EQ(a.scans[k].obs.size(), b.scans[k].obs.size());
      for (std::size_t j = 0; j < a.scans[k].obs.size(); ++j) {
        EXPECT_EQ(a.scans[k].obs[j].range, b.scans[k].obs[j].range);
        EXPECT_EQ(a.scans[k].obs[j].signature, b.scans[k].obs[j].signature);
        ++obs;
      }
    }
    ASSERT_EQ(a.truth.size(), b.truth.size());
    ASSERT_EQ(a.links.has_value(), b.links.has_value());
    if (a.links) {
      EXPECT_EQ(a.links->links, b.links->links);
    }
  }
  EXPECT_GT(obs, 0u);
  // A truncated file is an error naming it, not a crash.
  fs::resize_file(path, fs::file_size(path) - 3);
  try {
    ReadRecording(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": truncated"), std::string::npos);
  }
  std::ofstream(path) << "not a recording";
  EXPECT_THROW(ReadRecording(path), std::runtime_error);
  fs::remove(path);
}

}  // namespace
}  // namespace mapmesh
