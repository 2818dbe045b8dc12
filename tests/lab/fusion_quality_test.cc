// Fusion quality on the thesis circle pair (Fig. 59 layout): robot 2's bearing noise is
// swept, its map is aligned (unknown start poses) and fused into robot 1's global map, and
// the merged overlap landmarks are scored against the truth in robot 1's frame.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "lab/fusion_experiment.h"

namespace mapmesh::lab {
namespace {

std::vector<FusionSweepRow> BearingSweep(const std::vector<double>& values, int seeds) {
  FusionSweepOptions so;
  so.values = values;
  so.seeds = seeds;
  so.threads = 1;  // ctest runs tests side by side
  const auto make = [](double value, std::uint64_t seed) {
    return LoadScenario(MAPMESH_SOURCE_DIR "/scenarios/thesis_circle_pair.yaml",
                        {ParseOverride("robots.list[1].sensor.sigma_bearing_deg=" + std::to_string(value)),
                         ParseOverride("seed=" + std::to_string(seed))});
  };
  return SummariseFusionSweep(RunFusionSweep(make, so), so.trial.methods);
}

void CheckCiConsistency(const std::vector<FusionSweepRow>& rows) {
  std::printf("%-6s %-12s %6s %8s %8s %8s %8s %8s\n", "sigma", "method", "fused", "cons", "nees", "nees_1", "nees_2",
              "det");
  int checked = 0;
  for (const FusionSweepRow& r : rows) {
    std::printf("%-6.2f %-12s %3d/%-3d %8.3f %8.3f %8.3f %8.3f %8.2e\n", r.value,
                std::string(ToString(r.method)).c_str(), r.fused_runs, r.runs, r.merged.consistent_ratio, r.merged.nees,
                r.a.nees, r.b.nees, r.merged.det);
    EXPECT_GE(r.fused_runs, 0.9 * r.runs) << "alignment failed too often at sigma " << r.value;
    EXPECT_GT(r.merged.landmarks, 50 * r.fused_runs) << "the overlap is most of each map";
    EXPECT_GE(r.association_precision, 0.99);
    if (r.method != FusionMethod::kCiConstant) continue;
    ++checked;
    EXPECT_GE(r.merged.consistent_ratio, 0.85) << "sigma " << r.value;
    EXPECT_LE(r.merged.nees, 2.5) << "sigma " << r.value;
    EXPECT_LT(r.merged.nees, r.a.nees) << "sigma " << r.value;
    EXPECT_LT(r.merged.nees, r.b.nees) << "sigma " << r.value;
  }
  EXPECT_GT(checked, 0);
}

TEST(FusionQuality, CovarianceIntersectionStaysConsistentAsRobot2BearingNoiseGrows) {
  CheckCiConsistency(BearingSweep({0.5, 2.5, 4.5}, 10));
}

}  // namespace
}  // namespace mapmesh::lab
