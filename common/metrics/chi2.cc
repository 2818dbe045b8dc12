#include "common/metrics/chi2.h"

#include <cmath>

#include "common/check.h"

namespace mapmesh {

double Chi2Cdf(double x, int dof) {
  MAPMESH_CHECK(dof > 0 && dof % 2 == 0, "even degrees of freedom only");
  if (x <= 0.0) return 0.0;
  if (!std::isfinite(x)) return 1.0;
  // 1 - P(Poisson(h) < k). The terms exp(-h) h^i / i! are summed relative to the largest
  // one, walking down and up from it by the ratio h / i, so that neither exp(-h) nor h^i
  // under- or overflows for large dof; terms too small to matter end the walk.
  const double h = 0.5 * x;
  const int k = dof / 2;
  const int peak = std::min(k - 1, static_cast<int>(h));
  double sum = 1.0, term = 1.0;
  for (int i = peak; i > 0 && term > 1e-18 * sum; --i) sum += (term *= i / h);
  term = 1.0;
  for (int i = peak + 1; i < k && term > 1e-18 * sum; ++i) sum += (term *= h / i);
  const double log_peak = -h + peak * std::log(h) - std::lgamma(peak + 1.0);
  return 1.0 - std::min(1.0, sum * std::exp(log_peak));
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
