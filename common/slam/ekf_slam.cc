#include "common/slam/ekf_slam.h"

#include <algorithm>

namespace mapmesh {

void GatherState(const Eigen::VectorXd& x, const Eigen::MatrixXd& p, const std::vector<int>& idx, Eigen::VectorXd* xo,
                 Eigen::MatrixXd* po) {
  const int n = static_cast<int>(idx.size());
  xo->resize(n);
  po->resize(n, n);
  for (int i = 0; i < n; ++i) {
    (*xo)(i) = x(idx[i]);
    for (int j = 0; j < n; ++j) (*po)(i, j) = p(idx[i], idx[j]);
  }
}

EkfSlam::EkfSlam(const FilterNoise& noise, const EkfOptions& options) : noise_(noise), state_(options) {}

void EkfSlam::Predict(const OdometryControl& u, double dt) { state_.Predict(noise_, u, dt); }

bool EkfSlam::Update(const std::vector<std::pair<LandmarkId, Eigen::Vector2d>>& obs) {
  std::vector<EkfState::Measurement> m;
  m.reserve(obs.size());
  for (const auto& [id, z] : obs) m.push_back({slot_.at(id), z});
  return state_.Update(m, noise_.obs_cov);
}

void EkfSlam::Add(LandmarkId id, const Eigen::Vector2d& z) {
  slot_[id] = state_.Augment(z, noise_.obs_cov);
  ids_.push_back(id);
}

Eigen::MatrixXd EkfSlam::JointCov(const std::vector<LandmarkId>& ids) const {
  std::vector<int> idx{0, 1, 2};
  for (LandmarkId id : ids) {
    const int s = 3 + 2 * slot_.at(id);
    idx.push_back(s);
    idx.push_back(s + 1);
  }
  Eigen::VectorXd x;
  Eigen::MatrixXd p;
  GatherState(state_.x(), state_.P(), idx, &x, &p);
  return p;
}

Eigen::Matrix2d EkfSlam::CrossCov(LandmarkId a, LandmarkId b) const {
  return state_.P().block<2, 2>(3 + 2 * slot_.at(a), 3 + 2 * slot_.at(b));
}

LandmarkMap EkfSlam::Map() const {
  std::vector<LandmarkId> sorted = ids_;
  std::sort(sorted.begin(), sorted.end());
  LandmarkMap map;
  for (LandmarkId id : sorted) {
    const int s = 3 + 2 * slot_.at(id);
    Landmark l;
    l.id = id;
    l.mean = state_.x().segment<2>(s);
    l.cov = state_.P().block<2, 2>(s, s);
    map.landmarks.push_back(l);
  }
  return map;
}

void EkfSlam::FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const {
  *ids = ids_;
  std::sort(ids->begin(), ids->end());
  std::vector<int> idx{0, 1, 2};
  for (LandmarkId id : *ids) {
    idx.push_back(3 + 2 * slot_.at(id));
    idx.push_back(4 + 2 * slot_.at(id));
  }
  GatherState(state_.x(), state_.P(), idx, x, p);
}

}  // namespace mapmesh
