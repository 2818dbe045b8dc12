#pragma once
// The right-invariant EKF for 2D landmark SLAM (agent.slam: iekf; Barrau & Bonnabel 2015,
// Brossard, Barrau & Bonnabel 2018), beside the EKF and the compressed EKF.
//
// The state X = (R, p, l_1 .. l_n) is an element of the group SE_{1+n}(2): the robot's heading
// rotates the robot's position and every landmark's alike. Its error is right-invariant,
// X = exp(e) X^ with e = (rho_p, omega, rho_1 .. rho_n) in that order, and the filter keeps the
// covariance of e. Then:
// - motion (X U, U the body-frame increment of the unicycle or the car) leaves e unchanged
//   (F = I); the odometry noise enters as FilterNoise::MotionCov, moved into e by the estimate;
// - a range-bearing sighting of landmark i sees y = R^T (l_i - p) = y^ + R^^T (rho_i - rho_p):
//   its Jacobian in e is dz/dy R^^T [-I, 0, I], and H N = 0 for the three directions N that no
//   sighting observes (a global turn: omega = 1; a global shift: rho_p = rho_i = t), at any
//   estimate. The linearised filter gains no information along them (the EKF's false
//   observability, which makes long EKF runs overconfident, is gone by construction);
// - a new landmark's error is the robot's position error plus its sighting's: rho_l = rho_p + G dz.
// Every covariance it reports (robot_cov, JointCov, CrossCov, Map, FullState) is in the
// standard coordinates (x, y, theta, landmarks) of the other filters: delta p = rho_p + omega J p^,
// delta l = rho_l + omega J l^, delta theta = omega (J the quarter turn), to first order.
// A dense filter: each prediction adds a rank-3 term over every landmark (O(n^2)), as the EKF's update does.

#include <unordered_map>

#include "common/slam/landmark_filter.h"

namespace mapmesh {

class IekfSlam : public LandmarkFilter {
 public:
  explicit IekfSlam(const FilterNoise& noise);

  void Predict(const OdometryControl& u, double dt) override;
  bool Update(const std::vector<std::pair<LandmarkId, Eigen::Vector2d>>& obs) override;
  void Add(LandmarkId id, const Eigen::Vector2d& z) override;

  bool Has(LandmarkId id) const override { return slot_.count(id) > 0; }
  std::size_t size() const override { return ids_.size(); }
  std::vector<LandmarkId> Candidates() const override { return ids_; }
  Pose2 robot() const override { return {x_(0), x_(1), x_(2)}; }
  Eigen::Matrix3d robot_cov() const override;
  Eigen::Vector2d Mean(LandmarkId id) const override { return x_.segment<2>(Row(id)); }
  Eigen::MatrixXd JointCov(const std::vector<LandmarkId>& ids) const override;
  Eigen::Matrix2d CrossCov(LandmarkId a, LandmarkId b) const override;
  LandmarkMap Map() const override;
  void FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const override;

  // The covariance of the invariant error e (rows as x: robot position, heading, landmarks by slot).
  const Eigen::MatrixXd& invariant_cov() const { return p_; }
  // The state x = [robot x, y, theta, landmarks by slot].
  const Eigen::VectorXd& state() const { return x_; }
  // The Jacobian of the sighting of the landmark in slot `slot` with respect to e (2 x dim).
  Eigen::MatrixXd SightingJacobian(int slot) const;
  // X <- exp(e) X: the state moved by an invariant error e (dim).
  void Retract(const Eigen::VectorXd& e);

 private:
  Eigen::Index Row(LandmarkId id) const { return 3 + 2 * static_cast<Eigen::Index>(slot_.at(id)); }
  // dz/dy R^T of a sighting of the landmark at row `row`, and its predicted [range, bearing].
  Eigen::Matrix2d BodyJacobian(Eigen::Index row, Eigen::Vector2d* predicted) const;
  // The state and its standard-coordinate covariance on the given rows of x (robot rows 0-2 and
  // landmark rows): the invariant covariance gathered (GatherState) and mapped by de/d(standard).
  void Standard(const std::vector<int>& rows, Eigen::VectorXd* x, Eigen::MatrixXd* p) const;

  FilterNoise noise_;
  Eigen::VectorXd x_ = Eigen::VectorXd::Zero(3);
  Eigen::MatrixXd p_ = Eigen::MatrixXd::Zero(3, 3);
  std::vector<LandmarkId> ids_;  // by slot
  std::unordered_map<LandmarkId, int> slot_;
};

}  // namespace mapmesh
