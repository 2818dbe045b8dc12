#include "lab/thesis_alignment.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace mapmesh::lab {
namespace {

std::vector<std::vector<std::string>> ReadCsv(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::vector<std::string>> rows;
  for (std::string line; std::getline(f, line);) {
    std::vector<std::string> cells;
    std::stringstream s(line);
    for (std::string c; std::getline(s, c, ',');) cells.push_back(c);
    rows.push_back(cells);
  }
  return rows;
}

// A few trials per point: every CSV is complete, and the easy end of every curve succeeds
// (low noise, full overlap, every candidate true) while the hard end of Fig. 48 does not.
TEST(ThesisAlignment, WritesEveryFigureWithSensibleEnds) {
  const std::string dir = ::testing::TempDir() + "/thesis_alignment";
  std::filesystem::remove_all(dir);
  RunThesisAlignment(dir, {.trials = 3, .seed = 7});

  const auto fig46 = ReadCsv(dir + "/fig46_similarity.csv");
  ASSERT_EQ(fig46.size(), 1u + 3 * 10 * 2 + 10);  // header, 100-400 both matchers, 1000 sorted only
  for (const auto& r : fig46) {
    if (r[0] == "1000" && r[1] == "0.5") {
      EXPECT_GT(std::stod(r[3]), 0.9) << "sorted-sides candidate precision";
      EXPECT_DOUBLE_EQ(std::stod(r[5]), 1.0);
    }
  }
  const auto fig48 = ReadCsv(dir + "/fig48_noise.csv");
  ASSERT_EQ(fig48.size(), 1u + 3 * 10);
  std::map<std::string, double> success;
  for (std::size_t i = 1; i < fig48.size(); ++i) success[fig48[i][0] + "@" + fig48[i][1]] = std::stod(fig48[i][2]);
  EXPECT_DOUBLE_EQ(success["200@0.1"], 1.0);
  EXPECT_LT(success["200@1"], 0.8);  // a 2 m gate cannot hold every pair at sigma 1 m
  EXPECT_EQ(ReadCsv(dir + "/fig50_transforms.csv").size(), 1u + 3 * 10);
  const auto fig49 = ReadCsv(dir + "/fig49_51_match_ratio.csv");
  ASSERT_EQ(fig49.size(), 1u + 2 * 10);
  const auto fig52 = ReadCsv(dir + "/fig52_53_distance.csv");
  ASSERT_EQ(fig52.size(), 1u + 2 * 7);
  EXPECT_EQ(fig52[1][0], "euclidean");
  EXPECT_DOUBLE_EQ(std::stod(fig52[1][3]), 1.0);  // sigma 0.1 m: correct
  EXPECT_GT(std::stod(fig52.back()[2]), std::stod(fig52[7][2]))
      << "at sigma 2 m Mahalanobis consensus keeps more true pairs than a 2 m Euclidean gate";
}

}  // namespace
}  // namespace mapmesh::lab
