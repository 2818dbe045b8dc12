#include "common/metrics/chi2.h"

#include <cmath>

#include "common/check.h"

namespace mapmesh {

double Chi2Cdf(double x, int dof) {
  MAPMESH_CHECK(dof > 0 && dof % 2 == 0, "even degrees of freedom only");
  if (x <= 0.0) return 0.0;
  const double h = 0.5 * x;
  // Sum the Poisson terms in log space to stay finite for large dof.
  double term = std::exp(-h), sum = term;
  for (int i = 1; i < dof / 2; ++i) {
    term *= h / i;
    sum += term;
  }
  return 1.0 - std::min(1.0, sum);
}

double Chi2Quantile(double p, int dof) {
  MAPMESH_CHECK(p > 0.0 && p < 1.0, "probability in (0, 1)");
  double lo = 0.0, hi = dof + 10.0 * std::sqrt(2.0 * dof) + 50.0;
  while (Chi2Cdf(hi, dof) < p) hi *= 2.0;
  for (int it = 0; it < 200 && hi - lo > 1e-12 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (Chi2Cdf(mid, dof) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace mapmesh
