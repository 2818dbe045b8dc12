#include "common/slam/cekf_slam.h"

#include <algorithm>
#include <numeric>

#include "common/check.h"
#include "common/slam/ekf_slam.h"

namespace mapmesh {

CekfSlam::CekfSlam(const FilterNoise& noise, const CekfOptions& options, const EkfOptions& ekf_options)
    : noise_(noise),
      options_(options),
      ekf_options_(ekf_options),
      gx_(Eigen::VectorXd::Zero(3)),
      gp_(Eigen::MatrixXd::Zero(3, 3)),
      gfe_(Eigen::VectorXd::Zero(3)),
      gn_(3) {
  MAPMESH_CHECK(options.region_half_m > 0 && options.reach_m > 0, "CekfOptions: region and reach must be positive");
  StartPeriod();
}

bool CekfSlam::Has(LandmarkId id) const { return global_index_.count(id) || active_slot_.count(id); }

void CekfSlam::StartPeriod() {
  const Eigen::Vector2d c = gx_.head<2>();
  center_ = c;
  const double reach = options_.region_half_m + options_.reach_m;
  idx_a_ = {0, 1, 2};
  idx_b_.clear();
  active_ids_.clear();
  active_slot_.clear();
  passive_col_.clear();
  for (std::size_t g = 0; g < global_ids_.size(); ++g) {
    const int s = 3 + 2 * static_cast<int>(g);
    const Eigen::Vector2d m = gx_.segment<2>(s);
    if ((m - c).cwiseAbs().maxCoeff() <= reach) {
      active_slot_[global_ids_[g]] = static_cast<int>(active_ids_.size());
      active_ids_.push_back(global_ids_[g]);
      idx_a_.push_back(s);
      idx_a_.push_back(s + 1);
    } else {
      passive_col_[global_ids_[g]] = static_cast<int>(idx_b_.size());
      idx_b_.push_back(s);
      idx_b_.push_back(s + 1);
    }
  }
  period_active_ = active_ids_.size();
  Eigen::VectorXd xa;
  Eigen::MatrixXd paa;
  GatherState(gx_, gp_, idx_a_, &xa, &paa);
  // The active part keeps its first estimates (and the robot's propagated pose) across periods,
  // so that its Jacobians are the full EKF's.
  active_ = EkfState(xa, paa, gfe_(idx_a_), ekf_options_);
  pab1_ = gp_(idx_a_, idx_b_);
  const int na = static_cast<int>(idx_a_.size());
  phi_ = Eigen::MatrixXd::Identity(na, na);
  psi_ = Eigen::MatrixXd::Zero(na, na);
  theta_ = Eigen::VectorXd::Zero(na);
}

void CekfSlam::Predict(const OdometryControl& u, double dt) {
  const Eigen::Matrix3d j = active_.Predict(noise_, u, dt);
  // Only the robot rows of the active state move: Phi <- blockdiag(J, I) Phi.
  phi_.topRows<3>() = (j * phi_.topRows<3>()).eval();
  const Pose2 r = active_.robot();
  if ((Eigen::Vector2d(r.x, r.y) - center_).cwiseAbs().maxCoeff() > options_.region_half_m) Switch();
}

bool CekfSlam::Update(const std::vector<std::pair<LandmarkId, Eigen::Vector2d>>& obs) {
  if (obs.empty()) return true;
  std::vector<EkfState::Measurement> m;
  m.reserve(obs.size());
  for (const auto& [id, z] : obs) {
    const auto it = active_slot_.find(id);
    MAPMESH_CHECK(it != active_slot_.end(), "update of a passive landmark");
    m.push_back({it->second, z});
  }
  EkfState::UpdateTerms t;
  if (!active_.Update(m, noise_.obs_cov, &t)) return false;
  // ALGORITHMS.md section 3, from Phi before its own update.
  theta_.noalias() += phi_.transpose() * t.y;
  const Eigen::MatrixXd dpsi = phi_.transpose() * (t.beta * phi_);
  psi_ += 0.5 * (dpsi + dpsi.transpose());
  phi_ = (phi_ - t.mu * phi_).eval();
  return true;
}

void CekfSlam::Add(LandmarkId id, const Eigen::Vector2d& z) {
  MAPMESH_CHECK(!Has(id), "landmark id already in the filter");
  Matrix23 gr;
  const int slot = active_.Augment(z, noise_.obs_cov, &gr);
  active_slot_[id] = slot;
  active_ids_.push_back(id);
  // The new landmark's cross covariance with the passive part is G_r P_rb(k) =
  // G_r Phi_robot P_ab(k1): it joins Phi as two more rows.
  const Eigen::MatrixXd rows = gr * phi_.topRows<3>();
  phi_.conservativeResize(phi_.rows() + 2, Eigen::NoChange);
  phi_.bottomRows<2>() = rows;
}

void CekfSlam::BatchUpdate(Eigen::VectorXd& x, Eigen::MatrixXd& p, int n_old, std::vector<LandmarkId>* new_ids,
                           Eigen::VectorXd* fe) const {
  // (x, p) hold the state settled at the period start over [0, n_old), with room after it
  // for this period's new landmarks.
  std::vector<int> idx_a = idx_a_;
  for (std::size_t s = period_active_; s < active_ids_.size(); ++s) {
    const int g = n_old + 2 * static_cast<int>(s - period_active_);
    idx_a.push_back(g);
    idx_a.push_back(g + 1);
    new_ids->push_back(active_ids_[s]);
  }
  // ALGORITHMS.md section 3: x_b += P_ab(k1)^T theta; P_bb -= P_ab(k1)^T psi P_ab(k1);
  // P_ab = Phi P_ab(k1). The O(Nb^2 Na) term is computed on one triangle only.
  const int nb = static_cast<int>(idx_b_.size());
  const Eigen::VectorXd dxb = pab1_.transpose() * theta_;
  for (int i = 0; i < nb; ++i) x(idx_b_[i]) += dxb(i);
  if (nb > 0) {
    const Eigen::MatrixXd m = psi_ * pab1_;
    Eigen::MatrixXd owed(nb, nb);
    owed.triangularView<Eigen::Lower>() = pab1_.transpose() * m;
    for (int j = 0; j < nb; ++j) {
      const int gj = idx_b_[j];
      p(gj, gj) -= owed(j, j);
      for (int i = j + 1; i < nb; ++i) {
        const double v = owed(i, j);
        p(idx_b_[i], gj) -= v;
        p(gj, idx_b_[i]) -= v;
      }
    }
  }
  const Eigen::MatrixXd pab = phi_ * pab1_;
  for (std::size_t i = 0; i < idx_a.size(); ++i) x(idx_a[i]) = active_.x()(static_cast<Eigen::Index>(i));
  if (fe) {
    for (std::size_t i = 0; i < idx_a.size(); ++i)
      (*fe)(idx_a[i]) = active_.first_estimates()(static_cast<Eigen::Index>(i));
  }
  p(idx_a, idx_a) = active_.P();
  p(idx_a, idx_b_) = pab;
  p(idx_b_, idx_a) = pab.transpose();
}

void CekfSlam::Settled(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const {
  const int n = gn_ + 2 * static_cast<int>(active_ids_.size() - period_active_);
  *x = Eigen::VectorXd::Zero(n);
  *p = Eigen::MatrixXd::Zero(n, n);
  x->head(gn_) = gx_.head(gn_);
  p->topLeftCorner(gn_, gn_) = gp_.topLeftCorner(gn_, gn_);
  *ids = global_ids_;
  BatchUpdate(*x, *p, gn_, ids);
}

void CekfSlam::Switch() {
  const int n = gn_ + 2 * static_cast<int>(active_ids_.size() - period_active_);
  GrowStateStorage(gx_, gp_, gn_, n, &gfe_);  // the settled storage
  std::vector<LandmarkId> ids;
  BatchUpdate(gx_, gp_, gn_, &ids, &gfe_);  // in place
  for (LandmarkId id : ids) {
    global_index_[id] = static_cast<int>(global_ids_.size());
    global_ids_.push_back(id);
  }
  gn_ = n;
  ++switches_;
  StartPeriod();
}

Eigen::Vector2d CekfSlam::Mean(LandmarkId id) const { return active_.landmark(active_slot_.at(id)); }

Eigen::MatrixXd CekfSlam::JointCov(const std::vector<LandmarkId>& ids) const {
  std::vector<int> idx{0, 1, 2};
  for (LandmarkId id : ids) {
    const int s = 3 + 2 * active_slot_.at(id);
    idx.push_back(s);
    idx.push_back(s + 1);
  }
  return active_.P()(idx, idx);
}

Eigen::Matrix2d CekfSlam::CrossCov(LandmarkId a, LandmarkId b) const {
  // Active-active: the active covariance. Active-passive: P_ab(k) = Phi P_ab(k1). Passive-
  // passive: P_bb(k) = P_bb(k1) - P_ab(k1)^T psi P_ab(k1).
  const auto sa = active_slot_.find(a), sb = active_slot_.find(b);
  if (sa != active_slot_.end() && sb != active_slot_.end()) {
    return active_.P().block<2, 2>(3 + 2 * sa->second, 3 + 2 * sb->second);
  }
  if (sa != active_slot_.end()) {
    return phi_.middleRows<2>(3 + 2 * sa->second) * pab1_.middleCols<2>(passive_col_.at(b));
  }
  if (sb != active_slot_.end()) return CrossCov(b, a).transpose();
  const int ca = passive_col_.at(a), cb = passive_col_.at(b);
  return gp_.block<2, 2>(idx_b_[ca], idx_b_[cb]) -
         pab1_.middleCols<2>(ca).transpose() * (psi_ * pab1_.middleCols<2>(cb));
}

LandmarkMap CekfSlam::Map() const {
  // Passive marginals without a full batch update: O(Nb Na^2).
  LandmarkMap map;
  for (std::size_t s = 0; s < active_ids_.size(); ++s) {
    Landmark l;
    l.id = active_ids_[s];
    l.mean = active_.landmark(static_cast<int>(s));
    l.cov = active_.P().block<2, 2>(3 + 2 * s, 3 + 2 * s);
    map.landmarks.push_back(l);
  }
  const Eigen::MatrixXd psi_pab = psi_ * pab1_;
  for (std::size_t j = 0; j < idx_b_.size(); j += 2) {
    const int g = idx_b_[j];
    Landmark l;
    l.id = global_ids_[(g - 3) / 2];
    const auto cols = pab1_.middleCols<2>(j);
    l.mean = gx_.segment<2>(g) + cols.transpose() * theta_;
    l.cov = gp_.block<2, 2>(g, g) - cols.transpose() * psi_pab.middleCols<2>(j);
    map.landmarks.push_back(l);
  }
  std::sort(map.landmarks.begin(), map.landmarks.end(),
            [](const Landmark& a, const Landmark& b) { return a.id < b.id; });
  return map;
}

void CekfSlam::FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const {
  Eigen::VectorXd gx;
  Eigen::MatrixXd gp;
  std::vector<LandmarkId> gids;
  Settled(&gx, &gp, &gids);
  std::vector<int> order(gids.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return gids[a] < gids[b]; });
  std::vector<int> idx{0, 1, 2};
  ids->clear();
  for (int o : order) {
    idx.push_back(3 + 2 * o);
    idx.push_back(4 + 2 * o);
    ids->push_back(gids[o]);
  }
  GatherState(gx, gp, idx, x, p);
}

}  // namespace mapmesh
