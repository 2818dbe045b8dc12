#include "lab/slam_experiment.h"

#include <Eigen/Eigenvalues>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <chrono>
#include <cmath>
#include <sstream>
#include <unordered_map>

#include "agent/agent_node.h"
#include "agent/agent_setup.h"
#include "agent/sensor_sync.h"
#include "common/metrics/landmark_metrics.h"
#include "common/metrics/trajectory_metrics.h"
#include "common/slam/local_slam.h"
#include "sim_feeder/sources.h"

namespace mapmesh::lab {
namespace {

using PoseSample = SlamRunResult::PoseSample;

// A robot's estimator fed in time order, recording what the scoring needs.
class RobotRun : public SensorSync::Sink {
 public:
  RobotRun(const Scenario& sc, RobotId id, bool hide)
      : mapper_(MakeLocalMapper(sc, id)), sync_(*this, sc.agent.sync.frame_at_first_landmark), hide_(hide) {}

  void Move(const OdometryControl& u, double dt) override { mapper_->Predict(u, dt); }
  void ApplyScan(const Scan& scan, double stamp) override {
    if (!hide_) {
      mapper_->Observe(scan.obs, stamp);
    } else {
      std::vector<Observation> obs = scan.obs;
      for (Observation& o : obs) {
        if (o.kind == ObservationKind::kLandmark) o.signature = -1;
      }
      mapper_->Observe(obs, stamp);
      ScoreAssociations(scan.obs);
    }
    if (Mapped()) samples_.push_back({stamp, mapper_->pose(), mapper_->pose_cov()});
    for (const Observation& o : scan.obs) {
      if (o.kind == ObservationKind::kRobot)
        sightings_.push_back({stamp, static_cast<RobotId>(o.signature), o.range, o.bearing});
    }
  }
  void IntervalDone(const Odometry&) override {}
  bool Mapped() const override { return mapper_->size() > 0; }

  SensorSync& sync() { return sync_; }
  // The true identity of each landmark the estimator started (from the observation that
  // started it), when signatures were hidden.
  std::int32_t Identity(LandmarkId id) const {
    const auto it = identity_.find(id);
    return it == identity_.end() ? -1 : it->second;
  }
  const LocalMapper& mapper() const { return *mapper_; }
  const std::vector<PoseSample>& samples() const { return samples_; }
  const std::vector<SlamRunResult::Sighting>& sightings() const { return sightings_; }
  long associations = 0, wrong = 0, fresh = 0, dropped = 0;

 private:
  void ScoreAssociations(const std::vector<Observation>& truth_obs) {
    const auto* slam = dynamic_cast<const LocalSlam*>(mapper_.get());
    if (!slam) return;
    const auto& d = slam->last_decisions();
    for (std::size_t k = 0; k < truth_obs.size() && k < d.size(); ++k) {
      if (d[k].landmark == LocalSlam::kNotLandmark) continue;
      if (d[k].landmark < 0) {
        ++dropped;
        continue;
      }
      if (d[k].initialised) {
        identity_[d[k].landmark] = truth_obs[k].signature;
        ++fresh;
        continue;
      }
      ++associations;
      if (identity_[d[k].landmark] != truth_obs[k].signature) ++wrong;
    }
  }

  std::unique_ptr<LocalMapper> mapper_;
  SensorSync sync_;
  bool hide_;
  std::vector<PoseSample> samples_;
  std::vector<SlamRunResult::Sighting> sightings_;
  std::unordered_map<std::int64_t, std::int32_t> identity_;
};

// GPS fixes implying a faster jump than this are glitches.
constexpr double kMaxVehicleSpeedMps = 20.0;

}  // namespace

std::vector<SlamRunResult> RunSlam(const Scenario& scenario_in, const SlamRunOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  Scenario sc = scenario_in;
  Feed feed = MakeFeed(sc, options.datasets_root);
  std::map<RobotId, std::unique_ptr<RobotRun>> runs;
  std::map<RobotId, std::vector<GroundTruth>> truth;
  for (const RobotSpec& r : sc.robots) runs[r.id] = std::make_unique<RobotRun>(sc, r.id, options.hide_signatures);
  while (!feed.source->Done()) {
    const FeedBatch b = feed.source->Next();
    for (const Scan& s : b.scans) runs.at(s.robot_id)->sync().OnScan(s);
    for (const Odometry& o : b.odom) runs.at(o.robot_id)->sync().OnOdometry(o);
    for (const GroundTruth& g : b.truth) truth[g.robot_id].push_back(g);
  }
  const WorldTruth& world = feed.source->Truth();
  std::vector<int> seen;
  for (std::size_t i = 0; i < world.seen.size(); ++i) {
    if (world.seen[i]) seen.push_back(static_cast<int>(i));
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  std::vector<SlamRunResult> out;
  for (const auto& [id, run] : runs) {
    SlamRunResult r;
    r.seed = sc.seed;
    r.robot = id;
    r.wall_s = wall;
    LandmarkMap map = run->mapper().Map();
    if (options.hide_signatures) {
      for (Landmark& l : map.landmarks) l.signature = run->Identity(l.id);
    }
    r.landmarks = static_cast<int>(map.size());
    r.shape_sigma_m = map.shape_sigma_m;
    std::vector<double> sig;
    for (const Landmark& l : map.landmarks)
      sig.push_back(std::sqrt(std::max(0.0, l.cov.eigenvalues().real().maxCoeff())));
    if (!sig.empty()) {
      std::nth_element(sig.begin(), sig.begin() + static_cast<long>(sig.size() / 2), sig.end());
      r.median_sigma_m = sig[sig.size() / 2];
    }
    // The estimator's frame is the true pose when its stream began.
    std::optional<Pose2> origin;
    if (world.headings_known && run->sync().frame_origin_stamp()) {
      origin = TruthAt(truth[id], *run->sync().frame_origin_stamp());
    }
    if (!world.landmarks.empty()) {
      const MapQuality q = EvaluateOwnFrameMap(map, world.landmarks, seen, origin);
      r.map_evaluated = q.evaluated;
      r.map_aligned = q.aligned;
      r.landmark_rmse_m = q.rmse_m;
      r.landmark_nees = q.nees_mean;
      r.consistent_ratio = q.consistent_ratio;
      r.coverage = q.coverage;
      const MapQuality aligned = EvaluateFittedMap(map, world.landmarks, seen, origin);
      if (aligned.evaluated) r.landmark_rmse_aligned_m = aligned.rmse_m;
    }
    // Pose errors at every scan, when the frame's true origin is known.
    double nees = 0.0;
    std::vector<TimedPosition> est_track, ref_track;
    for (const PoseSample& s : run->samples()) est_track.push_back({s.t, {s.pose.x, s.pose.y}});
    if (origin) {
      for (const PoseSample& s : run->samples()) {
        const std::optional<Pose2> t = TruthAt(truth[id], s.t);
        if (!t) break;
        const Pose2 rel = origin->Inverse() * *t;
        ref_track.push_back({s.t, {rel.x, rel.y}});
        const Eigen::Vector3d e(s.pose.x - rel.x, s.pose.y - rel.y, WrapAngle(s.pose.theta - rel.theta));
        double e_nees = std::nan("");
        if (s.cov.determinant() > 0) {
          e_nees = e.dot(s.cov.ldlt().solve(e));
          nees += e_nees;
          ++r.pose_samples;
        }
        r.trace.push_back({s.t, e.head<2>().norm(), e(2), e_nees});
      }
      if (r.pose_samples > 0) r.pose_nees = nees / r.pose_samples;
      r.trajectory_rmse_m = CompareTrajectory(est_track, ref_track, false).rmse_m;
      r.trajectory_rmse_aligned_m = CompareTrajectory(est_track, ref_track, true).rmse_m;
    } else {
      // Unknown frame (GPS reference): compare at the reference fixes, glitches dropped,
      // after a least-squares rigid fit.
      for (const GroundTruth& g : truth[id]) ref_track.push_back({g.stamp, {g.x, g.y}});
      const TrajectoryError e = CompareTrajectory(est_track, DropImplausibleFixes(ref_track, kMaxVehicleSpeedMps),
                                                  true);
      r.trajectory_rmse_m = e.rmse_m;
      r.trajectory_rmse_aligned_m = e.rmse_m;
      r.trajectory_aligned = e.aligned;
      for (std::size_t i = 0; i < e.times.size(); ++i) {
        r.trace.push_back({e.times[i], e.errors_m[i], std::nan(""), std::nan("")});
      }
    }
    r.map = map;
    r.poses = run->samples();
    r.sightings = run->sightings();
    r.origin_truth = origin;
    r.landmark_truth = world.landmarks;
    r.associations = run->associations;
    r.wrong_associations = run->wrong;
    r.new_landmarks = run->fresh;
    r.dropped = run->dropped;
    out.push_back(r);
  }
  return out;
}

std::string SlamCsvHeader() {
  return "seed,robot,landmarks,map_frame,landmark_rmse_m,landmark_rmse_aligned_m,landmark_nees,consistent_ratio,coverage,shape_sigma_m,median_sigma_m,pose_samples,"
         "pose_nees,trajectory_rmse_m,trajectory_frame,associations,wrong_associations,new_landmarks,dropped,wall_s,"
         "trajectory_rmse_aligned_m";
}

std::string SlamCsvRow(const SlamRunResult& r) {
  std::ostringstream s;
  s << r.seed << ',' << r.robot << ',' << r.landmarks << ','
    << (!r.map_evaluated ? "none"
        : r.map_aligned  ? "aligned"
                         : "true_origin")
    << ',' << r.landmark_rmse_m << ',' << r.landmark_rmse_aligned_m << ',' << r.landmark_nees << ','
    << r.consistent_ratio << ',' << r.coverage << ',' << r.shape_sigma_m << ',' << r.median_sigma_m << ','
    << r.pose_samples << ',' << r.pose_nees << ',' << r.trajectory_rmse_m << ','
    << (r.trajectory_aligned ? "aligned" : "true_origin") << ',' << r.associations << ',' << r.wrong_associations << ','
    << r.new_landmarks << ',' << r.dropped << ',' << r.wall_s << ',' << r.trajectory_rmse_aligned_m;
  return s.str();
}

}  // namespace mapmesh::lab
