#include "lab/victoria_world.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include "common/config/scenario.h"

namespace mapmesh::lab {
namespace {

// A planted run of 8 spans of 100 s each, driven at 1 m/s: the odd spans (1, 3, 5, 7) drive
// along the x axis through a row of trees, the even ones each in a valley of its own 200 m
// apart, so the spans sharing the most landmarks pairwise are 0, 2, 4 and 6 (0-based).
SlamRunResult PlantedRun() {
  SlamRunResult r;
  for (int i = 0; i < 40; ++i) {  // the shared row: trees at x = 0..195, 3 m off the axis
    Landmark l;
    l.id = i;
    l.mean = {5.0 * i, 3.0};
    r.map.landmarks.push_back(l);
  }
  for (int k = 0; k < 4; ++k) {  // 5 trees beside each valley
    for (int i = 0; i < 5; ++i) {
      Landmark l;
      l.id = 100 + 10 * k + i;
      l.mean = {10.0 * i, 200.0 * (k + 1) + 3.0};
      r.map.landmarks.push_back(l);
    }
  }
  for (int span = 0; span < 8; ++span) {
    const double y = span % 2 == 0 ? 0.0 : 200.0 * (span / 2 + 1);
    for (int s = 0; s < 100; ++s) {
      SlamRunResult::PoseSample p;
      p.t = span * 100.0 + s;
      p.pose = Pose2{s * 1.0, y, 0.0};
      p.cov = Eigen::Matrix3d::Identity();
      r.poses.push_back(p);
    }
  }
  return r;
}

TEST(VictoriaWorld, KeepsTheSpansThatShareTheMostLandmarks) {
  VictoriaWorldOptions o;
  o.visible_m = 4.0;
  o.waypoint_spacing_m = 5.0;
  const VictoriaWorld w = DeriveVictoriaWorld(PlantedRun(), o);
  EXPECT_EQ(w.landmarks.size(), 60u);
  EXPECT_EQ(w.kept, (std::vector<int>{0, 2, 4, 6}));
  ASSERT_EQ(w.paths.size(), 4u);
  // Each drives x = 0..99: the trees at x <= 99 + 3.x m within 4 m of the path: x = 0..100 (21).
  for (int r = 0; r < 4; ++r) {
    EXPECT_EQ(w.neighbourhood[r], 21) << r;
    for (int q = 0; q < 4; ++q) EXPECT_EQ(w.shared[r][q], 21) << r << q;
    EXPECT_NEAR(w.length_m[r], 99.0, 1e-9);
    const auto& p = w.paths[r];
    EXPECT_EQ(p.front(), Eigen::Vector2d(0, 0));
    EXPECT_EQ(p.back(), Eigen::Vector2d(99, 0));
    for (std::size_t i = 1; i + 1 < p.size(); ++i) EXPECT_GE((p[i] - p[i - 1]).norm(), 5.0 - 1e-9);
  }
}

TEST(VictoriaWorld, SpansTooShortToDriveAreNeverKept) {
  SlamRunResult run = PlantedRun();
  // Span 3 (0-based 2) parks: every pose at the origin.
  for (auto& p : run.poses)
    if (p.t >= 200.0 && p.t < 300.0) p.pose = Pose2{};
  VictoriaWorldOptions o;
  o.visible_m = 4.0;
  const VictoriaWorld w = DeriveVictoriaWorld(run, o);
  EXPECT_EQ(std::count(w.kept.begin(), w.kept.end(), 2), 0);
  EXPECT_THROW(DeriveVictoriaWorld(SlamRunResult{}, o), std::invalid_argument);
  o.robots = 9;
  EXPECT_THROW(DeriveVictoriaWorld(run, o), std::invalid_argument);
}

TEST(VictoriaWorld, TheScenarioDrivesEachKeptSpanOverTheTrees) {
  const VictoriaWorld w = DeriveVictoriaWorld(PlantedRun(), VictoriaWorldOptions{});
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "mapmesh_victoria_world_test";
  std::filesystem::create_directories(dir / "data");
  std::ofstream(dir / "data/trees.csv") << VictoriaLandmarksCsv(w);
  const std::string yaml = VictoriaScenarioYaml(w, "data/trees.csv");
  const Scenario sc = ParseScenario(yaml, (dir / "victoria_sim.yaml").string());
  ASSERT_EQ(sc.world.landmarks.size(), w.landmarks.size());
  for (std::size_t i = 0; i < w.landmarks.size(); ++i)
    EXPECT_LT((sc.world.landmarks[i] - w.landmarks[i]).norm(), 1e-3) << i;
  ASSERT_EQ(sc.robots.size(), 4u);
  for (std::size_t r = 0; r < 4; ++r) {
    const RobotSpec& robot = sc.robots[r];
    EXPECT_EQ(robot.id, static_cast<RobotId>(r + 1));
    EXPECT_TRUE(robot.start_given);
    EXPECT_LT((Eigen::Vector2d(robot.start.x, robot.start.y) - w.paths[r].front()).norm(), 1e-3);
    ASSERT_EQ(robot.path.points.size() + 1, w.paths[r].size());  // the start is not a waypoint
    EXPECT_FALSE(robot.path.loop);
    EXPECT_TRUE(robot.sensor.signatures);
  }
  // Long enough for the longest path at the scenario's speed.
  EXPECT_GE(sc.duration_s, 99.0 / sc.robots[0].motion.speed_mps);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mapmesh::lab
