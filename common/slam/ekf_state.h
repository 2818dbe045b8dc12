#pragma once
// A dense EKF over [robot pose (3), landmarks (2 each)]: the full EKF-SLAM of thesis 3.2.2,
// and the active part of the compressed filter. Storage grows geometrically, so adding a
// landmark does not copy the whole covariance.

#include <Eigen/Core>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/slam/motion_model.h"
#include "common/slam/observation_model.h"

namespace mapmesh {

// Makes room for n entries in a state vector and its covariance, keeping the first `used`:
// storage grows geometrically (at least doubling), so the O(N^2) copy is rare.
void GrowStateStorage(Eigen::VectorXd& x, Eigen::MatrixXd& p, int used, int n);

class EkfState {
 public:
  // The robot at the origin of its own frame, with zero covariance (it defines the frame).
  EkfState();
  // A given state (x: 3 + 2k, P: square of the same size).
  EkfState(const Eigen::VectorXd& x, const Eigen::MatrixXd& p);

  int size() const { return n_; }
  int landmarks() const { return (n_ - 3) / 2; }
  Pose2 robot() const { return {x_(0), x_(1), x_(2)}; }
  Eigen::Vector2d landmark(int slot) const { return x_.segment<2>(3 + 2 * slot); }
  auto x() const { return x_.head(n_); }
  auto P() const { return P_.topLeftCorner(n_, n_); }

  // EKF prediction (thesis eq. 19-22): only the robot rows and columns of P change; the
  // landmark block is not touched. Returns the robot Jacobian of the motion.
  Eigen::Matrix3d Predict(const MotionModel& model, const OdometryControl& u, double dt,
                          const Eigen::Matrix2d& control_cov);

  // One observation of a landmark slot.
  struct Measurement {
    int slot = 0;
    Eigen::Vector2d z = Eigen::Vector2d::Zero();  // range, bearing
  };
  // What the compressed filter needs from an update, all taken before it changes P:
  // beta = H^T S^-1 H, y = H^T S^-1 nu, mu = P beta.
  struct UpdateTerms {
    Eigen::MatrixXd beta, mu;
    Eigen::VectorXd y;
  };
  // Batch EKF update with every measurement of a scan at once (thesis eq. 23-25), in the
  // standard form followed by symmetrisation. False (and no change) if S is not positive
  // definite.
  bool Update(const std::vector<Measurement>& obs, const Eigen::Matrix2d& obs_cov,
              UpdateTerms* terms = nullptr);

  // Predicted observation of a slot and its Jacobians.
  Eigen::Vector2d Predicted(int slot, Matrix23* h_robot, Eigen::Matrix2d* h_landmark) const;

  // Initialises a landmark from z through the inverse observation model; its cross
  // covariances follow from the robot's rows. Returns the new slot; g_robot receives the
  // Jacobian of the initialisation with respect to the robot.
  int Augment(const Eigen::Vector2d& z, const Eigen::Matrix2d& obs_cov, Matrix23* g_robot = nullptr);

 private:
  void Reserve(int n);

  Eigen::VectorXd x_;
  Eigen::MatrixXd P_;
  int n_ = 3;
};

}  // namespace mapmesh
