#pragma once
// The compressed EKF in submaps joined by least squares (agent.slam: cekf_submaps; Downs 3.1
// and 4.3, Huang et al.'s I-SLSJF). The filter (LocalSlam, compressed EKF) runs in a submap
// that starts afresh, the robot at its origin with zero covariance, and ends at a trigger
// (SubmapOptions: distance, duration, landmark count, heading uncertainty). Each finished
// submap, its end pose and landmarks with their joint covariance, goes to the SubmapJoiner,
// which relinearises them all. An EKF never runs long enough for its linearisation error to
// grow, and the joiner undoes the rest.
//
// The map is the joined map of the finished submaps and the open one, with marginal
// covariances, in the first submap's frame (the estimator's frame). Landmark ids are keys of
// the joined map: the signature with known association; otherwise a submap's landmarks are
// matched to the joined map's when they close (chi-square gate, unique), or get new keys.

#include <memory>
#include <optional>
#include <vector>

#include "common/map/submap_codec.h"
#include "common/slam/local_slam.h"
#include "common/slam/submap_joiner.h"

namespace mapmesh {

// A closed submap as it travels (common/map/submap_codec.h): its estimate with the covariance
// factored and rounded as the wire holds it; nullopt when that covariance is not positive
// definite.
std::optional<WireSubmap> ToWire(const SubmapEstimate& estimate, const SubmapId& id, double opened_s, double closed_s);

// A joined estimate as a landmark map: ids are the keys, marginal covariances, the shape
// precision from the cross-covariances; signatures are the keys with known association, else
// unknown.
LandmarkMap JoinedLandmarkMap(const JoinedMap& joined, bool signatures);

class SubmapSlam : public LocalMapper {
 public:
  SubmapSlam(const FilterNoise& noise, const LocalSlamOptions& options);

  void Predict(const OdometryControl& u, double dt) override;
  void Observe(const std::vector<Observation>& obs, double stamp) override;
  LandmarkMap Map() const override;
  Pose2 pose() const override;
  Eigen::Matrix3d pose_cov() const override;
  std::size_t size() const override;
  const MapperStats& stats() const override;

  std::size_t submaps_closed() const { return joiner_.submaps(); }
  const SubmapJoiner& joiner() const { return joiner_; }

  // A closed submap as it went to the joiner, with the scan stamps that opened and closed it:
  // what the agent publishes, once each (issue J1). Every submap closed so far, in order; a
  // submap that held no information (none went to the joiner) is not among them.
  struct Closed {
    SubmapEstimate estimate;
    double opened_s = 0.0, closed_s = 0.0;
  };
  const std::vector<Closed>& closed() const { return closed_; }
  std::size_t SubmapsClosed() const override { return closed_.size(); }
  std::optional<WireSubmap> ClosedSubmap(std::size_t i, const SubmapId& id) const override {
    return ToWire(closed_.at(i).estimate, id, closed_.at(i).opened_s, closed_.at(i).closed_s);
  }
  std::optional<WireSubmap> CurrentSubmap(const SubmapId& id) const override {
    const std::optional<SubmapEstimate> open = OpenSubmap();
    if (!open) return std::nullopt;
    return ToWire(*open, id, opened_s_.value_or(last_stamp_s_), last_stamp_s_);
  }

 private:
  // The open submap as the joiner takes it: keys assigned, nothing if it holds no information;
  // re-placed by the divergence guard when *replaced is set true.
  std::optional<SubmapEstimate> OpenSubmap(bool* replaced = nullptr) const;
  // Each joined landmark as the open submap's origin (the joined end pose) sees it, and the
  // covariance of that relative position.
  void Relative(std::vector<Eigen::Vector2d>* rel, std::vector<Eigen::Matrix2d>* rel_cov) const;
  // The divergence guard (SubmapOptions::divergence_guard): re-places the open submap's state
  // x, p (landmarks ids) when it disagrees with the joined map; true if it did.
  bool Replace(Eigen::VectorXd* x, Eigen::MatrixXd* p, const std::vector<LandmarkId>& ids) const;
  // Keys for the open submap's landmarks (ids): matched into the joined map, or new ones
  // counted from next_key_; -1 for a landmark to leave out (ambiguous).
  std::vector<std::int64_t> Keys(const Eigen::VectorXd& x, const Eigen::MatrixXd& p,
                                 const std::vector<LandmarkId>& ids) const;
  bool ShouldClose() const;
  void Close();

  FilterNoise noise_;
  LocalSlamOptions options_;  // for the submaps' filter (kCekf)
  SubmapOptions submap_;
  bool known_association_;
  std::unique_ptr<LocalSlam> current_;
  SubmapJoiner joiner_;
  std::uint32_t next_key_ = 0;  // unknown association: the next new landmark's key
  double travelled_m_ = 0.0, elapsed_s_ = 0.0;
  std::vector<Closed> closed_;
  std::optional<double> opened_s_;  // the first scan stamp of the open submap
  double last_stamp_s_ = 0.0;
  MapperStats closed_stats_;
  std::uint64_t diverged_ = 0;
  mutable MapperStats stats_;
  // The map, made when asked and kept until the next Predict or Observe.
  mutable bool fresh_ = false;
  mutable LandmarkMap map_;
};

}  // namespace mapmesh
