#pragma once
// Full EKF-SLAM (thesis 3.2.2): the reference the compressed filter must equal.

#include <unordered_map>

#include "common/slam/ekf_state.h"
#include "common/slam/landmark_filter.h"

namespace mapmesh {

class EkfSlam : public LandmarkFilter {
 public:
  explicit EkfSlam(const FilterNoise& noise, const EkfOptions& options = {});

  void Predict(const OdometryControl& u, double dt) override;
  bool Update(const std::vector<std::pair<LandmarkId, Eigen::Vector2d>>& obs) override;
  void Add(LandmarkId id, const Eigen::Vector2d& z) override;

  bool Has(LandmarkId id) const override { return slot_.count(id) > 0; }
  std::size_t size() const override { return ids_.size(); }
  std::vector<LandmarkId> Candidates() const override { return ids_; }
  Pose2 robot() const override { return state_.robot(); }
  Eigen::Matrix3d robot_cov() const override { return state_.P().topLeftCorner<3, 3>(); }
  Eigen::Vector2d Mean(LandmarkId id) const override { return state_.landmark(slot_.at(id)); }
  Eigen::MatrixXd JointCov(const std::vector<LandmarkId>& ids) const override;
  Eigen::Matrix2d CrossCov(LandmarkId a, LandmarkId b) const override;
  LandmarkMap Map() const override;
  void FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const override;

 private:
  FilterNoise noise_;
  EkfState state_;
  std::vector<LandmarkId> ids_;  // by slot
  std::unordered_map<LandmarkId, int> slot_;
};

// Gathers the rows and columns of state indices idx from (x, p).
void GatherState(const Eigen::VectorXd& x, const Eigen::MatrixXd& p, const std::vector<int>& idx, Eigen::VectorXd* xo,
                 Eigen::MatrixXd* po);

}  // namespace mapmesh
