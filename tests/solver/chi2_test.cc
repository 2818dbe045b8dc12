#include "common/solver/chi2.h"

#include <gtest/gtest.h>

#include "common/metrics/landmark_metrics.h"

namespace mapmesh {
namespace {

TEST(Chi2, KnownQuantiles) {
  // Standard table values.
  EXPECT_NEAR(Chi2Quantile(0.95, 2), kChi2Dof2P95, 1e-9);
  EXPECT_NEAR(Chi2Quantile(0.99, 2), 9.2103, 1e-4);
  EXPECT_NEAR(Chi2Quantile(0.999, 2), 13.8155, 1e-4);
  EXPECT_NEAR(Chi2Quantile(0.95, 4), 9.4877, 1e-4);
  EXPECT_NEAR(Chi2Quantile(0.99, 10), 23.2093, 1e-4);
  EXPECT_NEAR(Chi2Quantile(0.99, 40), 63.6907, 1e-3);
  EXPECT_NEAR(Chi2Cdf(Chi2Quantile(0.3, 6), 6), 0.3, 1e-9);
  EXPECT_DOUBLE_EQ(Chi2Cdf(-1.0, 2), 0.0);
}

TEST(Chi2, LargeDegreesOfFreedom) {
  // exp(-x/2) underflows beyond x ~ 1490: alignment tests sums over a thousand inliers.
  // Reference values from scipy.stats.chi2.
  EXPECT_NEAR(Chi2Quantile(0.999, 1000), 1143.9171, 1e-3);
  EXPECT_NEAR(Chi2Quantile(0.999, 1756), 1944.8473, 1e-3);
  EXPECT_NEAR(Chi2Cdf(2000.0, 1900), 0.945793, 1e-5);
  EXPECT_NEAR(Chi2Cdf(1e5, 2), 1.0, 1e-15);
  EXPECT_LT(Chi2Cdf(100.0, 1000), 1e-100);
}

TEST(Chi2, OddDegreesOfFreedom) {
  // The residual of a rigid 2D fit to n pairs has 2n - 3. Reference values from
  // scipy.stats.chi2.
  EXPECT_NEAR(Chi2Quantile(0.95, 1), 3.841459, 1e-6);
  EXPECT_NEAR(Chi2Quantile(0.99, 3), 11.344867, 1e-6);
  EXPECT_NEAR(Chi2Quantile(0.999, 17), 40.790215, 1e-5);
  EXPECT_NEAR(Chi2Cdf(7.814728, 3), 0.95, 1e-6);
  // Between its even neighbours.
  EXPECT_GT(Chi2Quantile(0.99, 5), Chi2Quantile(0.99, 4));
  EXPECT_LT(Chi2Quantile(0.99, 5), Chi2Quantile(0.99, 6));
}

}  // namespace
}  // namespace mapmesh
