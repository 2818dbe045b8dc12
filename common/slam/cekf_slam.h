#pragma once
// Compressed EKF-SLAM (Guivant & Nebot 2001; thesis 3.2.3, with the digest's corrected
// equations in ALGORITHMS.md section 3). The state is split into an active part (the robot
// and the landmarks it can see while it stays inside a square region) and a passive part.
// Inside the region, prediction and update cost O(Na^2); three auxiliary matrices record what
// the passive part owes, and a batch update (O(N^2 Na)) settles it when the robot leaves the
// region. Within a period the linearisations are the full EKF's, so the result equals the
// full EKF's up to rounding.

#include <Eigen/Core>
#include <unordered_map>

#include "common/slam/ekf_state.h"
#include "common/slam/landmark_filter.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

struct CekfOptions {
  double region_half_m = 5.0;  // agent.region_half_m: a switch happens when the robot is this far (inf-norm) from the
                               // region centre
  double reach_m = 0.0;        // agent.region_reach_m: active landmarks lie within region_half_m + reach_m (inf-norm)
                               // of it; 0: the sensor's range plus 4 m (LocalSlamOptions::ForSensor), which CekfSlam
                               // requires resolved

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md).
  template <typename Reader>
  void Read(Reader& r) {
    r.GetPositiveUpTo("region_half_m", region_half_m, limits::kMaxLengthM);
    r.GetInRange("region_reach_m", reach_m, 0.0, limits::kMaxLengthM);
  }
};

class CekfSlam : public LandmarkFilter {
 public:
  CekfSlam(const FilterNoise& noise, const CekfOptions& options, const EkfOptions& ekf_options = {});

  void Predict(const OdometryControl& u, double dt) override;
  bool Update(const std::vector<std::pair<LandmarkId, Eigen::Vector2d>>& obs) override;
  void Add(LandmarkId id, const Eigen::Vector2d& z) override;

  bool Has(LandmarkId id) const override;
  std::size_t size() const override { return global_ids_.size() + (active_ids_.size() - period_active_); }
  std::vector<LandmarkId> Candidates() const override { return active_ids_; }
  Pose2 robot() const override { return active_.robot(); }
  Eigen::Matrix3d robot_cov() const override { return active_.P().topLeftCorner<3, 3>(); }
  Eigen::Vector2d Mean(LandmarkId id) const override;
  Eigen::MatrixXd JointCov(const std::vector<LandmarkId>& ids) const override;
  Eigen::Matrix2d CrossCov(LandmarkId a, LandmarkId b) const override;
  LandmarkMap Map() const override;
  void FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const override;

  // Settles the passive part (the batch update) and starts a new region around the robot.
  void Switch();
  int switches() const { return switches_; }
  std::size_t active_landmarks() const { return active_ids_.size(); }

 private:
  // The batch update, applied in place to (x, p) holding the settled state of the period
  // start over [0, n_old); this period's new landmarks go after it, their ids to new_ids.
  // fe, if given, alongside x, receives the active part's first estimates.
  void BatchUpdate(Eigen::VectorXd& x, Eigen::MatrixXd& p, int n_old, std::vector<LandmarkId>* new_ids,
                   Eigen::VectorXd* fe = nullptr) const;
  // A copy of the full state at the current time, over global indices.
  void Settled(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const;
  void StartPeriod();

  FilterNoise noise_;
  CekfOptions options_;
  EkfOptions ekf_options_;
  // The settled state at the start of the period, over global indices: [robot, landmarks in
  // the order they were added]. Its active rows are stale during the period.
  Eigen::VectorXd gx_;  // storage with spare capacity: the state is its first gn_ entries
  Eigen::MatrixXd gp_;
  Eigen::VectorXd gfe_;  // first estimates alongside gx_ (EkfState::first_estimates)
  int gn_ = 3;
  std::vector<LandmarkId> global_ids_;
  std::unordered_map<LandmarkId, int> global_index_;
  // The period.
  Eigen::Vector2d center_ = Eigen::Vector2d::Zero();
  EkfState active_;
  std::vector<LandmarkId> active_ids_;  // by active slot
  std::unordered_map<LandmarkId, int> active_slot_;
  std::size_t period_active_ = 0;   // active landmarks that existed at the period start
  std::vector<int> idx_a_, idx_b_;  // state indices (global) of the period-start active and passive parts
  std::unordered_map<LandmarkId, int> passive_col_;  // a passive landmark's first column in P_ab
  Eigen::MatrixXd pab1_;                             // P_ab at the period start
  Eigen::MatrixXd phi_;                              // Phi: P_ab(k) = Phi P_ab(k1)
  Eigen::MatrixXd psi_;                              // psi: P_bb(k) = P_bb(k1) - P_ab(k1)^T psi P_ab(k1)
  Eigen::VectorXd theta_;                            // theta: x_b(k) = x_b(k1) + P_ab(k1)^T theta
  int switches_ = 0;
};

}  // namespace mapmesh
