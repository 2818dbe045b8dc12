#include "common/slam/iekf_slam.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "common/slam/ekf_slam.h"
#include "common/slam/observation_model.h"

namespace mapmesh {
namespace {

// J p: the quarter turn of a position, how it moves when the heading error turns it.
Eigen::Vector2d Quarter(const Eigen::Vector2d& p) { return {-p.y(), p.x()}; }

}  // namespace

IekfSlam::IekfSlam(const FilterNoise& noise) : noise_(noise) {}

void IekfSlam::Predict(const OdometryControl& u, double dt) {
  if (!(dt > 0)) return;
  const Eigen::Matrix3d q = noise_.MotionCov(robot(), u, dt);  // of the standard error at the end pose
  const Pose2 next = MoveRobot(noise_.motion, robot(), u, dt);
  x_.head<3>() = next.Vector();
  // The noise in e: rho_p = dp - dtheta J p, omega = dtheta, rho_l = -dtheta J l (at X^ after the
  // motion). The error itself is unchanged by the motion (F = I).
  const Eigen::Index n = x_.size();
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n, 3);
  m(0, 0) = 1.0;
  m(1, 1) = 1.0;
  m(2, 2) = 1.0;
  m.block<2, 1>(0, 2) = -Quarter(x_.head<2>());
  for (Eigen::Index r = 3; r < n; r += 2) m.block<2, 1>(r, 2) = -Quarter(x_.segment<2>(r));
  p_.noalias() += m * q * m.transpose();
}

Eigen::Matrix2d IekfSlam::BodyJacobian(Eigen::Index row, Eigen::Vector2d* predicted) const {
  const double c = std::cos(x_(2)), s = std::sin(x_(2));
  Eigen::Matrix2d rt;
  rt << c, s, -s, c;
  const Eigen::Vector2d y = rt * (x_.segment<2>(row) - x_.head<2>());
  const double r2 = std::max(y.squaredNorm(), 1e-12), r = std::sqrt(r2);
  *predicted = Eigen::Vector2d(r, std::atan2(y.y(), y.x()));
  Eigen::Matrix2d dz_dy;
  dz_dy << y.x() / r, y.y() / r, -y.y() / r2, y.x() / r2;
  return dz_dy * rt;
}

Eigen::MatrixXd IekfSlam::SightingJacobian(int slot) const {
  const Eigen::Index row = 3 + 2 * static_cast<Eigen::Index>(slot);
  Eigen::Vector2d zhat;
  const Eigen::Matrix2d b = BodyJacobian(row, &zhat);
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(2, x_.size());
  h.leftCols<2>() = -b;
  h.middleCols<2>(row) = b;
  return h;
}

bool IekfSlam::Update(const std::vector<std::pair<LandmarkId, Eigen::Vector2d>>& obs) {
  const auto k = static_cast<Eigen::Index>(obs.size());
  if (k == 0) return true;
  const Eigen::Index n = x_.size(), m = 2 * k;
  std::vector<Eigen::Matrix2d> b(obs.size());
  std::vector<Eigen::Index> rows(obs.size());
  Eigen::VectorXd nu(m);
  Eigen::MatrixXd pht(n, m);  // P H^T, from H's two blocks per sighting
  for (Eigen::Index i = 0; i < k; ++i) {
    rows[i] = Row(obs[i].first);
    Eigen::Vector2d zhat;
    b[i] = BodyJacobian(rows[i], &zhat);
    nu(2 * i) = obs[i].second(0) - zhat(0);
    nu(2 * i + 1) = WrapAngle(obs[i].second(1) - zhat(1));
    pht.middleCols<2>(2 * i) = (p_.middleCols<2>(rows[i]) - p_.leftCols<2>()) * b[i].transpose();
  }
  Eigen::MatrixXd s(m, m);
  for (Eigen::Index i = 0; i < k; ++i) {
    s.middleRows<2>(2 * i) = b[i] * (pht.middleRows<2>(rows[i]) - pht.topRows<2>());
  }
  s = 0.5 * (s + s.transpose()).eval();
  for (Eigen::Index i = 0; i < k; ++i) s.block<2, 2>(2 * i, 2 * i) += noise_.obs_cov;
  const Eigen::LLT<Eigen::MatrixXd> llt(s);
  if (llt.info() != Eigen::Success) return false;
  const Eigen::VectorXd e = pht * llt.solve(nu);
  p_.noalias() -= pht * llt.solve(pht.transpose());
  p_ = 0.5 * (p_ + p_.transpose()).eval();
  Retract(e);
  return true;
}

void IekfSlam::Retract(const Eigen::VectorXd& e) {
  const double w = e(2);
  const double c = std::cos(w), s = std::sin(w);
  // V(w) of SE(2)'s exponential: sin(w)/w and (1 - cos(w))/w, by series near 0.
  const double a = std::abs(w) < 1e-6 ? 1.0 - w * w / 6.0 : s / w;
  const double bb = std::abs(w) < 1e-6 ? w / 2.0 : (1.0 - c) / w;
  Eigen::Matrix2d rot, v;
  rot << c, -s, s, c;
  v << a, -bb, bb, a;
  x_.head<2>() = (rot * x_.head<2>() + v * e.head<2>()).eval();
  x_(2) = WrapAngle(x_(2) + w);
  for (Eigen::Index r = 3; r < x_.size(); r += 2) {
    x_.segment<2>(r) = (rot * x_.segment<2>(r) + v * e.segment<2>(r)).eval();
  }
}

void IekfSlam::Add(LandmarkId id, const Eigen::Vector2d& z) {
  Eigen::Matrix2d gz;
  const Eigen::Vector2d l = InverseRangeBearing(robot(), z, nullptr, &gz);
  const Eigen::Index n = x_.size();
  x_.conservativeResize(n + 2);
  x_.segment<2>(n) = l;
  p_.conservativeResize(n + 2, n + 2);
  // rho_l = rho_p + (world-frame Jacobian of the sighting) dz.
  p_.block(n, 0, 2, n) = p_.block(0, 0, 2, n);
  p_.block(0, n, n, 2) = p_.block(n, 0, 2, n).transpose();
  p_.block<2, 2>(n, n) = p_.topLeftCorner<2, 2>() + gz * noise_.obs_cov * gz.transpose();
  slot_[id] = static_cast<int>(ids_.size());
  ids_.push_back(id);
}

void IekfSlam::Standard(const std::vector<int>& rows, Eigen::VectorXd* x, Eigen::MatrixXd* p) const {
  GatherState(x_, p_, rows, x, p);
  const auto m = static_cast<Eigen::Index>(rows.size());
  Eigen::MatrixXd t = Eigen::MatrixXd::Identity(m, m);
  const auto heading = std::find(rows.begin(), rows.end(), 2) - rows.begin();
  for (Eigen::Index i = 0; i < m; ++i) {
    const int r = rows[i];
    if (r == 2) continue;
    const int base = r < 2 ? 0 : 3 + 2 * ((r - 3) / 2);
    t(i, heading) = Quarter(x_.segment<2>(base))(r - base);
  }
  *p = t * *p * t.transpose();
}

Eigen::Matrix3d IekfSlam::robot_cov() const {
  Eigen::VectorXd x;
  Eigen::MatrixXd p;
  Standard({0, 1, 2}, &x, &p);
  return p;
}

Eigen::MatrixXd IekfSlam::JointCov(const std::vector<LandmarkId>& ids) const {
  std::vector<int> rows{0, 1, 2};
  for (LandmarkId id : ids) {
    rows.push_back(static_cast<int>(Row(id)));
    rows.push_back(static_cast<int>(Row(id)) + 1);
  }
  Eigen::VectorXd x;
  Eigen::MatrixXd p;
  Standard(rows, &x, &p);
  return p;
}

Eigen::Matrix2d IekfSlam::CrossCov(LandmarkId a, LandmarkId b) const {
  const Eigen::Index ra = Row(a), rb = Row(b);
  const Eigen::Vector2d ja = Quarter(x_.segment<2>(ra)), jb = Quarter(x_.segment<2>(rb));
  return p_.block<2, 2>(ra, rb) + p_.block<2, 1>(ra, 2) * jb.transpose() + ja * p_.block<1, 2>(2, rb) +
         p_(2, 2) * ja * jb.transpose();
}

LandmarkMap IekfSlam::Map() const {
  std::vector<LandmarkId> sorted = ids_;
  std::sort(sorted.begin(), sorted.end());
  LandmarkMap map;
  map.landmarks.reserve(sorted.size());
  for (LandmarkId id : sorted) {
    Landmark l;
    l.id = id;
    l.mean = Mean(id);
    l.cov = CrossCov(id, id);
    map.landmarks.push_back(l);
  }
  return map;
}

void IekfSlam::FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const {
  *ids = ids_;
  std::sort(ids->begin(), ids->end());
  std::vector<int> rows{0, 1, 2};
  for (LandmarkId id : *ids) {
    rows.push_back(static_cast<int>(Row(id)));
    rows.push_back(static_cast<int>(Row(id)) + 1);
  }
  Standard(rows, x, p);
}

}  // namespace mapmesh
