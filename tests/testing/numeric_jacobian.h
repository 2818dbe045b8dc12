#pragma once
// Central-difference Jacobians for checking analytic ones in tests.

#include <Eigen/Core>
#include <functional>

namespace mapmesh::testing {

// d f / d x at x, for f: R^n -> R^m. angle_rows marks outputs to wrap (differences of angles).
inline Eigen::MatrixXd NumericJacobian(const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f,
                                       const Eigen::VectorXd& x, double h = 1e-6,
                                       const std::vector<int>& angle_rows = {}) {
  const Eigen::VectorXd f0 = f(x);
  Eigen::MatrixXd j(f0.size(), x.size());
  for (int i = 0; i < x.size(); ++i) {
    Eigen::VectorXd xp = x, xm = x;
    xp(i) += h;
    xm(i) -= h;
    Eigen::VectorXd d = f(xp) - f(xm);
    for (int r : angle_rows) d(r) = std::remainder(d(r), 2.0 * M_PI);
    j.col(i) = d / (2.0 * h);
  }
  return j;
}

}  // namespace mapmesh::testing
