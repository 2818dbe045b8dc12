#include "common/metrics/chi2.h"

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

}  // namespace
}  // namespace mapmesh
