#pragma once
// An agent's local map: a landmark filter (full or compressed EKF) with data association,
// outlier gating and, optionally, tentative landmarks that need a second sighting.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/slam/cekf_slam.h"
#include "common/slam/data_association.h"
#include "common/slam/landmark_filter.h"
#include "common/slam/local_mapper.h"
#include "common/slam/submap_joiner.h"

namespace mapmesh {

// What a local estimator knows of its robot's range-bearing sensor.
struct SensorSpec {
  double max_range_m = 8.0;
  double sigma_range_m = 0.05;
  double sigma_bearing_rad = 0.0175;
  bool signatures = false;  // it reports which landmark it saw
};

// When agent.slam is cekf_submaps, a submap ends (and the next starts afresh, the robot at its
// origin with zero covariance) after the first scan at which any of these holds (0: not used).
struct SubmapOptions {
  double distance_m = 10.0;         // agent.submap_distance_m: the robot has travelled this far in it
  double duration_s = 0.0;          // agent.submap_duration_s: it has lasted this long
  int landmarks = 0;                // agent.submap_landmarks: it holds this many landmarks
  double heading_sigma_deg = 5.0;   // agent.submap_heading_sigma_deg: the robot's heading standard deviation in
                                    // it has grown this large (before the EKF linearises at a poor heading)
  double association_gate = 13.82;  // unknown association: chi-square (2 dof) gate of a submap's landmark
                                    // against the joined map's (99.9 %)
  // agent.join_window, agent.join_relinearise_m (submap_joiner.h): 0.1 m, a landmark's sigma on
  // MRCLAM; without it MRCLAM 1 robot 5 at 3 deg submaps keeps one landmark 2.7 m off.
  JoinerOptions join{.relinearise_m = 0.1};
  // The divergence guard (known association): a submap whose landmarks the joined map holds
  // mostly disagree with it (at least 2, more than half, outside association_gate) started
  // where the robot was lost, not where the last one ended (a heading error no sighting
  // corrected, as after a blind turn on bad odometry). It is re-placed by a rigid fit of those
  // landmarks, its placement made unknown (5 m, 2 rad: the joiner places it by what it
  // shares), when they are at least 3 spanning 1 m or more and at most a quarter of them then
  // disagree; counted in MapperStats::diverged (docs/EXPERIMENTS.md "Other odometry rates").
  bool divergence_guard = true;  // agent.divergence_guard

  template <typename Reader>
  void Read(Reader& r) {
    r.GetInRange("submap_distance_m", distance_m, 0.0, limits::kMaxLengthM);
    r.GetInRange("submap_duration_s", duration_s, 0.0, limits::kMaxPeriodS);
    r.GetInRange("submap_landmarks", landmarks, 0, 1000000);
    r.GetInRange("submap_heading_sigma_deg", heading_sigma_deg, 0.0, 180.0);
    r.GetInRange("join_window", join.window, 1, 100000);
    r.GetInRange("join_relinearise_m", join.relinearise_m, 0.0, limits::kMaxLengthM);
    r.Get("divergence_guard", divergence_guard);
  }
};

struct LocalSlamOptions {
  SlamMethod
      filter = SlamMethod::kCekf;  // agent.slam (LocalSlam runs kCekf, kEkf or kIekf; SubmapSlam runs kCekfSubmaps;
                                   // kDeadReckoning is the baseline mapper)
  SubmapOptions submaps;
  AssociationOptions association;
  EkfOptions ekf;  // linearisation, of either filter
  CekfOptions cekf;
  bool tentative = false;                  // agent.tentative: a new landmark enters the map only when seen twice
  double tentative_gate_m = 1.0;           // agent.tentative_gate_m: a second sighting lands within this of the first
  double tentative_timeout_s = 30.0;       // agent.tentative_timeout_s: tentative landmarks not seen again by then
                                           // are forgotten
  double min_range_m = 0.0;                // agent.min_range_m: observations outside [min, max] range are dropped
  double max_range_m = 0.0;                // agent.max_range_m; 0: the sensor's max range plus 5 sigma (ForSensor;
                                           // LocalSlam given 0 applies no limit)
  double new_landmark_separation_m = 0.5;  // unknown association: new landmarks of one scan closer than this are one

  // These options for a robot with this sensor: the association method and the limits left
  // to the sensor (0 above) resolved. Readings beyond what the sensor can see, allowing for its
  // noise, are refused: one forged reading 30 km away must not end up in the map.
  LocalSlamOptions ForSensor(const SensorSpec& sensor) const {
    LocalSlamOptions o = *this;
    o.association.method = association.Resolve(sensor.signatures);
    o.max_range_m = max_range_m > 0 ? max_range_m : sensor.max_range_m + 5.0 * sensor.sigma_range_m;
    const double range = max_range_m > 0 ? max_range_m : sensor.max_range_m;
    if (!(cekf.reach_m > 0)) o.cekf.reach_m = range + 4.0;
    return o;
  }

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md), its parts' included.
  template <typename Reader>
  void Read(Reader& r) {
    r.GetChoice("slam", filter, kSlamMethods);
    association.Read(r);
    r.Get("tentative", tentative);
    r.GetPositiveUpTo("tentative_gate_m", tentative_gate_m, limits::kMaxLengthM);
    r.GetPositiveUpTo("tentative_timeout_s", tentative_timeout_s, limits::kMaxPeriodS);
    r.GetInRange("min_range_m", min_range_m, 0.0, limits::kMaxLengthM);
    r.GetInRange("max_range_m", max_range_m, 0.0, limits::kMaxLengthM);
    cekf.Read(r);
    ekf.Read(r);
    submaps.Read(r);
  }
};

// The map's shape precision (LandmarkMap::shape_sigma_m) from the cross-covariances between
// each landmark and its nearest neighbour (found through the Delaunay triangulation): those of
// a filter, or cross_cov(i, j) of the map's landmarks i and j.
double ShapeSigma(const LandmarkMap& map, const std::function<Eigen::Matrix2d(std::size_t, std::size_t)>& cross_cov);
double ShapeSigma(const LandmarkMap& map, const LandmarkFilter& filter);

class LocalSlam : public LocalMapper {
 public:
  LocalSlam(const FilterNoise& noise, const LocalSlamOptions& options);

  void Predict(const OdometryControl& u, double dt) override;
  void Observe(const std::vector<Observation>& obs, double stamp) override;
  LandmarkMap Map() const override;
  Pose2 pose() const override { return filter_->robot(); }
  Eigen::Matrix3d pose_cov() const override { return filter_->robot_cov(); }
  std::size_t size() const override { return filter_->size(); }
  const MapperStats& stats() const override { return stats_; }
  // The whole state, x = [robot, landmarks by increasing id], and its covariance.
  void FullState(Eigen::VectorXd* x, Eigen::MatrixXd* p, std::vector<LandmarkId>* ids) const {
    filter_->FullState(x, p, ids);
  }

  // What became of each observation of the last scan, in the order given to Observe: the
  // landmark id it was fused into or started, or one of these.
  static constexpr std::int64_t kDropped = -1;  // outlier, ambiguous, invalid, out of range
  static constexpr std::int64_t kHeld = -2;     // tentative
  static constexpr std::int64_t kNotLandmark = -3;
  struct Decision {
    std::int64_t landmark = kDropped;
    bool initialised = false;  // the observation started this landmark
  };
  const std::vector<Decision>& last_decisions() const { return decisions_; }

 private:
  struct Tentative {
    Eigen::Vector2d position;  // in the map frame
    std::int32_t signature;
    double stamp;
  };
  // Adds a landmark now, or holds it as tentative; returns true if it entered the filter.
  bool AddOrHold(LandmarkId id, std::int32_t signature, const Eigen::Vector2d& z, double stamp);

  FilterNoise noise_;
  LocalSlamOptions options_;
  std::unique_ptr<LandmarkFilter> filter_;
  std::vector<Tentative> tentatives_;
  LandmarkId next_id_ = 0;
  MapperStats stats_;
  std::vector<Decision> decisions_;
};

}  // namespace mapmesh
