// Monte Carlo study of data association (slow: label slow;montecarlo, not in the default run).
// The cluttered world hides landmark identities from the estimator; JCBB must pair
// observations with the wrong landmark less often than ICNN.

#include <gtest/gtest.h>

#include "lab/slam_experiment.h"

namespace mapmesh {
namespace {

double WrongRate(const std::string& method, int seeds, long* total) {
  long wrong = 0, assoc = 0;
  for (int seed = 1; seed <= seeds; ++seed) {
    const Scenario sc = LoadScenario(MAPMESH_SOURCE_DIR "/scenarios/cluttered.yaml",
                                     {ParseOverride("agent.association=" + method),
                                      ParseOverride("seed=" + std::to_string(seed))});
    lab::SlamRunOptions o;
    o.hide_signatures = true;
    for (const lab::SlamRunResult& r : lab::RunSlam(sc, o)) {
      wrong += r.wrong_associations;
      assoc += r.associations;
    }
  }
  *total = assoc;
  return static_cast<double>(wrong) / static_cast<double>(assoc);
}

TEST(AssociationMonteCarlo, JcbbMakesFewerWrongAssociationsThanIcnnInClutter) {
  long n_icnn = 0, n_jcbb = 0;
  const double icnn = WrongRate("icnn", 10, &n_icnn);
  const double jcbb = WrongRate("jcbb", 10, &n_jcbb);
  std::printf("cluttered world, 10 seeds: wrong associations ICNN %.3f %% of %ld, JCBB %.3f %% of %ld\n", 100 * icnn,
              n_icnn, 100 * jcbb, n_jcbb);
  EXPECT_GT(n_icnn, 10000);
  EXPECT_GT(n_jcbb, 10000);
  EXPECT_LT(jcbb, icnn);
}

}  // namespace
}  // namespace mapmesh
