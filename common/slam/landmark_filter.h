#pragma once
// The interface of the landmark SLAM filters (full EKF and compressed EKF): what data
// association and the agent need from them.

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/slam/motion_model.h"

namespace mapmesh {

using LandmarkId = std::uint32_t;

// Process and measurement noise of a filter.
struct FilterNoise {
  MotionModel motion;
  // Covariance of the model's control vector averaged over control_period_s. Odometry
  // errors are white noise of spectral density control_cov * control_period_s (Density()):
  // the mean control over an interval dt errs by Density() / dt, and the pose gains
  // MotionCov over it, the same whether odometry comes at 4 or 100 Hz and however an
  // interval is split at scans.
  Eigen::Matrix2d control_cov = Eigen::Matrix2d::Identity();
  double control_period_s = 0.1;
  Eigen::Matrix2d obs_cov = Eigen::Matrix2d::Identity();  // of [range, bearing]
  Eigen::Matrix2d Density() const { return control_cov * control_period_s; }
  // The covariance the pose gains moving by u over dt from pose (MotionNoise).
  Eigen::Matrix3d MotionCov(const Pose2& pose, const OdometryControl& u, double dt) const {
    return MotionNoise(motion, pose, u, dt, Density());
  }
};

class LandmarkFilter {
 public:
  virtual ~LandmarkFilter() = default;

  virtual void Predict(const OdometryControl& u, double dt) = 0;
  // One batch update with observations z = [range, bearing] of landmarks already in the
  // filter (for the compressed filter: of candidates). False if the innovation covariance
  // was not positive definite (the state is then unchanged).
  virtual bool Update(const std::vector<std::pair<LandmarkId, Eigen::Vector2d>>& obs) = 0;
  // Adds a landmark initialised from an observation.
  virtual void Add(LandmarkId id, const Eigen::Vector2d& z) = 0;

  virtual bool Has(LandmarkId id) const = 0;
  virtual std::size_t size() const = 0;
  // The landmarks an observation may be associated with now.
  virtual std::vector<LandmarkId> Candidates() const = 0;
  virtual Pose2 robot() const = 0;
  virtual Eigen::Matrix3d robot_cov() const = 0;
  // Mean of a candidate landmark.
  virtual Eigen::Vector2d Mean(LandmarkId id) const = 0;
  // Covariance of [robot pose; candidate landmarks ids...], (3 + 2k) square.
  virtual Eigen::MatrixXd JointCov(const std::vector<LandmarkId>& ids) const = 0;
  // Cross-covariance E[(m_a - mean_a)(m_b - mean_b)^T] of two landmarks (any two, not only
  // candidates).
  virtual Eigen::Matrix2d CrossCov(LandmarkId a, LandmarkId b) const = 0;
  // Every landmark with its mean and marginal covariance, by increasing id.
  virtual LandmarkMap Map() const = 0;
  // The whole state with landmarks by increasing id: x = [robot, landmarks], P.
  virtual void FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const = 0;
};

}  // namespace mapmesh
