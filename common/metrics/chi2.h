#pragma once
// Chi-square distribution with an even number of degrees of freedom (2 per 2D measurement),
// where the CDF has a closed form: P(X <= x) = 1 - exp(-x/2) sum_{i<k} (x/2)^i / i!, k = dof/2.

namespace mapmesh {

// P(X <= x) for X ~ chi2(dof), dof even and positive.
double Chi2Cdf(double x, int dof);
// The p-quantile (0 < p < 1) of chi2(dof), dof even and positive.
double Chi2Quantile(double p, int dof);

}  // namespace mapmesh
