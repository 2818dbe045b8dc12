#include "common/solver/chi2.h"

#include <boost/math/distributions/chi_squared.hpp>
#include <cmath>

#include "common/check.h"

namespace mapmesh {

double Chi2Cdf(double x, double dof) {
  MAPMESH_CHECK(dof > 0, "positive degrees of freedom");
  if (x <= 0.0) return 0.0;
  if (!std::isfinite(x)) return 1.0;
  return boost::math::cdf(boost::math::chi_squared_distribution<double>(dof), x);
}

double Chi2Quantile(double p, double dof) {
  MAPMESH_CHECK(p > 0.0 && p < 1.0, "probability in (0, 1)");
  MAPMESH_CHECK(dof > 0, "positive degrees of freedom");
  return boost::math::quantile(boost::math::chi_squared_distribution<double>(dof), p);
}

}  // namespace mapmesh
