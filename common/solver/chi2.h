#pragma once
// The chi-squared distribution (Boost.Math), for gates and consistency tests: 2 degrees of
// freedom per 2D measurement, 2n - 3 for the residual of a rigid fit to n point pairs.

namespace mapmesh {

// P(X <= x) for X ~ chi2(dof), dof > 0.
double Chi2Cdf(double x, double dof);
// The p-quantile (0 < p < 1) of chi2(dof), dof > 0.
double Chi2Quantile(double p, double dof);

}  // namespace mapmesh
