#include "common/slam/ekf_state.h"

#include <Eigen/Cholesky>

#include "common/check.h"

namespace mapmesh {

EkfState::EkfState(const EkfOptions& options)
    : options_(options), x_(Eigen::VectorXd::Zero(3)), P_(Eigen::MatrixXd::Zero(3, 3)), fe_(Eigen::VectorXd::Zero(3)) {}

EkfState::EkfState(const Eigen::VectorXd& x, const Eigen::MatrixXd& p, const EkfOptions& options)
    : EkfState(x, p, x, options) {}

EkfState::EkfState(const Eigen::VectorXd& x, const Eigen::MatrixXd& p, const Eigen::VectorXd& first_estimates,
                   const EkfOptions& options)
    : options_(options), x_(x), P_(p), fe_(first_estimates), n_(static_cast<int>(x.size())) {
  MAPMESH_CHECK(x.size() >= 3 && (x.size() - 3) % 2 == 0, "state is [robot, landmarks]");
  MAPMESH_CHECK(p.rows() == x.size() && p.cols() == x.size());
  MAPMESH_CHECK(first_estimates.size() == x.size(), "a first estimate for every state entry");
}

void GrowStateStorage(Eigen::VectorXd& x, Eigen::MatrixXd& p, int used, int n, Eigen::VectorXd* alongside) {
  if (n <= x.size()) return;
  const int cap = std::max<int>(n, static_cast<int>(x.size()) * 2);
  Eigen::VectorXd gx = Eigen::VectorXd::Zero(cap);
  Eigen::MatrixXd gp = Eigen::MatrixXd::Zero(cap, cap);
  gx.head(used) = x.head(used);
  gp.topLeftCorner(used, used) = p.topLeftCorner(used, used);
  x.swap(gx);
  p.swap(gp);
  if (alongside) {
    Eigen::VectorXd ga = Eigen::VectorXd::Zero(cap);
    ga.head(used) = alongside->head(used);
    alongside->swap(ga);
  }
}

void EkfState::Reserve(int n) { GrowStateStorage(x_, P_, n_, n, &fe_); }

namespace {

// d(p')/d(theta) of a pose-dependent move or of a point placed from the robot, J (p' - p), in
// the last column of the first two rows of jac; for the motion models and the inverse
// observation model, with p the robot's position, this is exactly their analytic Jacobian.
template <typename Jacobian>
void SetHeadingColumn(const Eigen::Vector2d& moved, const Eigen::Vector2d& from, Jacobian& jac) {
  jac(0, 2) = -(moved.y() - from.y());
  jac(1, 2) = moved.x() - from.x();
}

}  // namespace

Eigen::Matrix3d EkfState::Predict(const FilterNoise& noise, const OdometryControl& u, double dt) {
  Eigen::Matrix3d j;
  const Eigen::Matrix3d q = noise.MotionCov(robot(), u, dt);
  const Pose2 next = MoveRobot(noise.motion, robot(), u, dt, &j);
  // FEJ: the position change counted from the propagated position, not the updated one, so
  // that the Jacobians of successive steps chain to one global rotation (Huang et al. 2008).
  if (options_.first_estimates_jacobians) SetHeadingColumn({next.x, next.y}, fe_.head<2>(), j);
  x_.head<3>() = next.Vector();
  fe_.head<3>() = next.Vector();
  const Eigen::Matrix3d prr = P_.topLeftCorner<3, 3>();
  P_.topLeftCorner<3, 3>() = j * prr * j.transpose() + q;
  const int m = n_ - 3;
  if (m > 0) {
    P_.block(0, 3, 3, m) = (j * P_.block(0, 3, 3, m)).eval();
    P_.block(3, 0, m, 3) = P_.block(0, 3, 3, m).transpose();
  }
  return j;
}

Eigen::Vector2d EkfState::Predicted(int slot, Matrix23* h_robot, Eigen::Matrix2d* h_landmark) const {
  return ObserveRangeBearing(robot(), landmark(slot), h_robot, h_landmark);
}

void EkfState::Jacobians(int slot, Matrix23* h_robot, Eigen::Matrix2d* h_landmark) const {
  if (!options_.first_estimates_jacobians) {
    Predicted(slot, h_robot, h_landmark);
    return;
  }
  // The range-bearing Jacobians depend on the robot's position only (not its heading).
  ObserveRangeBearing({fe_(0), fe_(1), fe_(2)}, first_estimate(slot), h_robot, h_landmark);
}

bool EkfState::Update(const std::vector<Measurement>& obs, const Eigen::Matrix2d& obs_cov, UpdateTerms* terms) {
  const int k = static_cast<int>(obs.size());
  if (k == 0) return true;
  const int m = 2 * k;
  const auto P = P_.topLeftCorner(n_, n_);
  std::vector<Matrix23> hr(k);
  std::vector<Eigen::Matrix2d> hm(k);
  Eigen::VectorXd nu(m);
  Eigen::MatrixXd pht(n_, m);  // P H^T, using the sparsity of H
  for (int i = 0; i < k; ++i) {
    const int idx = 3 + 2 * obs[i].slot;
    MAPMESH_CHECK(obs[i].slot >= 0 && idx + 1 < n_, "observation of an unknown slot");
    const Eigen::Vector2d zhat = Predicted(obs[i].slot, nullptr, nullptr);
    Jacobians(obs[i].slot, &hr[i], &hm[i]);
    nu(2 * i) = obs[i].z(0) - zhat(0);
    nu(2 * i + 1) = WrapAngle(obs[i].z(1) - zhat(1));
    pht.middleCols<2>(2 * i) = P.leftCols<3>() * hr[i].transpose() + P.middleCols<2>(idx) * hm[i].transpose();
  }
  Eigen::MatrixXd s(m, m);
  for (int i = 0; i < k; ++i) {
    const int idx = 3 + 2 * obs[i].slot;
    s.middleRows<2>(2 * i) = hr[i] * pht.topRows<3>() + hm[i] * pht.middleRows<2>(idx);
  }
  s = 0.5 * (s + s.transpose()).eval();
  for (int i = 0; i < k; ++i) s.block<2, 2>(2 * i, 2 * i) += obs_cov;
  const Eigen::LLT<Eigen::MatrixXd> llt(s);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::VectorXd s_inv_nu = llt.solve(nu);
  if (terms) {
    Eigen::MatrixXd h = Eigen::MatrixXd::Zero(m, n_);
    for (int i = 0; i < k; ++i) {
      const int idx = 3 + 2 * obs[i].slot;
      h.block<2, 3>(2 * i, 0) = hr[i];
      h.block<2, 2>(2 * i, idx) = hm[i];
    }
    terms->beta = h.transpose() * llt.solve(h);
    terms->y = h.transpose() * s_inv_nu;
    terms->mu = P * terms->beta;
  }
  // x += K nu with K = P H^T S^-1;  P -= K S K^T = P H^T S^-1 H P.
  x_.head(n_) += pht * s_inv_nu;
  x_(2) = WrapAngle(x_(2));
  const Eigen::MatrixXd w = llt.solve(pht.transpose());
  auto Pm = P_.topLeftCorner(n_, n_);
  Pm.noalias() -= pht * w;
  Pm = 0.5 * (Pm + Pm.transpose()).eval();
  return true;
}

int EkfState::Augment(const Eigen::Vector2d& z, const Eigen::Matrix2d& obs_cov, Matrix23* g_robot) {
  Matrix23 gr;
  Eigen::Matrix2d gz;
  const Eigen::Vector2d m = InverseRangeBearing(robot(), z, &gr, &gz);
  // FEJ: at the new landmark's first estimate (m) and the robot's propagated position, as
  // its later observations will be (Huang et al. 2008).
  if (options_.first_estimates_jacobians) SetHeadingColumn(m, fe_.head<2>(), gr);
  const int n = n_;
  Reserve(n + 2);
  x_.segment<2>(n) = m;
  fe_.segment<2>(n) = m;
  P_.block(n, 0, 2, n) = gr * P_.block(0, 0, 3, n);
  P_.block(0, n, n, 2) = P_.block(n, 0, 2, n).transpose();
  P_.block<2, 2>(n, n) = gr * P_.topLeftCorner<3, 3>() * gr.transpose() + gz * obs_cov * gz.transpose();
  n_ = n + 2;
  if (g_robot) *g_robot = gr;
  return (n - 3) / 2;
}

}  // namespace mapmesh
