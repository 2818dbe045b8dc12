// Estimation quality against ground truth, from the same in-process runs mapmesh-lab makes.

#include <gtest/gtest.h>

#include "lab/slam_experiment.h"

namespace mapmesh {
namespace {

// Thesis default scenario (Fig. 59 world, thesis robots and noise), 2 minutes, known
// association, 20 seeds: the compressed EKF must be consistent.
TEST(SlamQuality, ThesisDefaultScenarioIsConsistent) {
  double landmark_nees = 0.0, pose_nees = 0.0, rmse = 0.0;
  int n = 0;
  for (int seed = 1; seed <= 20; ++seed) {
    const Scenario sc = LoadScenario(MAPMESH_SOURCE_DIR "/scenarios/thesis_circle_pair.yaml",
                                     {ParseOverride("duration_s=120"), ParseOverride("seed=" + std::to_string(seed))});
    for (const lab::SlamRunResult& r : lab::RunSlam(sc, {})) {
      ASSERT_TRUE(r.map_evaluated);
      ASSERT_FALSE(r.map_aligned);
      ASSERT_GT(r.pose_samples, 200);
      landmark_nees += r.landmark_nees;
      pose_nees += r.pose_nees;
      rmse += r.landmark_rmse_m;
      ++n;
    }
  }
  landmark_nees /= n;
  pose_nees /= n;
  rmse /= n;
  RecordProperty("landmark_nees", std::to_string(landmark_nees));
  RecordProperty("pose_nees", std::to_string(pose_nees));
  std::printf("thesis default, 20 seeds x 2 robots: landmark NEES %.2f, pose NEES %.2f, landmark RMSE %.3f m\n",
              landmark_nees, pose_nees, rmse);
  EXPECT_GE(landmark_nees, 1.0);
  EXPECT_LE(landmark_nees, 3.0);
  EXPECT_GE(pose_nees, 1.5);
  EXPECT_LE(pose_nees, 4.5);
}

}  // namespace
}  // namespace mapmesh
