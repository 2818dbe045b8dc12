// The acceptance run of M5 (label slow): 100 seeded runs at every bearing noise of thesis
// Fig. 61 (0.5-4.5 deg), the same checks as the quality test.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "lab/fusion_experiment.h"

namespace mapmesh::lab {
namespace {

TEST(FusionMonteCarlo, CovarianceIntersectionOverAHundredRunsPerBearingNoise) {
  FusionSweepOptions so;
  so.values = {0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5};
  so.seeds = 100;
  const auto make = [](double value, std::uint64_t seed) {
    return LoadScenario(MAPMESH_SOURCE_DIR "/scenarios/thesis_circle_pair.yaml",
                        {ParseOverride("robots.list[1].sensor.sigma_bearing_deg=" + std::to_string(value)),
                         ParseOverride("seed=" + std::to_string(seed))});
  };
  const auto rows = SummariseFusionSweep(RunFusionSweep(make, so), so.trial.methods);
  std::printf("%s", FusionSweepCsv("bearing_sigma_deg", rows).c_str());
  for (const FusionSweepRow& r : rows) {
    EXPECT_GE(r.fused_runs, 90) << "sigma " << r.value;
    if (r.method != FusionMethod::kCiConstant) continue;
    EXPECT_GE(r.merged.consistent_ratio, 0.85) << "sigma " << r.value;
    EXPECT_LE(r.merged.nees, 2.5) << "sigma " << r.value;
    EXPECT_LT(r.merged.nees, r.a.nees) << "sigma " << r.value;
    EXPECT_LT(r.merged.nees, r.b.nees) << "sigma " << r.value;
  }
}

}  // namespace
}  // namespace mapmesh::lab
