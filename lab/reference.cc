#include "lab/reference.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>

#include "agent/agent_setup.h"
#include "agent/sensor_sync.h"
#include "common/metrics/landmark_metrics.h"
#include "common/metrics/trajectory_metrics.h"
#include "sim_feeder/sources.h"

namespace mapmesh::lab {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// A robot's streams in time order into its batch log, through the agent's own SensorSync (so
// the intervals are split at the scans exactly as the agent splits them); odometry from the
// start (the frame is the start pose, not the first landmark's).
class LogSink : public SensorSync::Sink {
 public:
  LogSink(RobotId robot, const FilterNoise& noise, double min_range_m, double max_range_m, std::optional<Pose2> start)
      : builder_(robot, noise, min_range_m, max_range_m, start), sync_(*this, false) {}
  void Move(const OdometryControl& u, double dt) override { builder_.Move(u, dt); }
  void ApplyScan(const Scan& scan, double stamp) override { builder_.Scan(stamp, scan.obs); }
  void IntervalDone(const Odometry&) override {}
  bool Mapped() const override { return true; }
  SensorSync& sync() { return sync_; }
  const BatchRobotLog& log() const { return builder_.log(); }

 private:
  BatchLogBuilder builder_;
  SensorSync sync_;
};

std::string Describe(const RobustKernel& k) {
  char buf[64];
  switch (k.loss) {
    case RobustLoss::kNone: return "none";
    case RobustLoss::kHuber: std::snprintf(buf, sizeof buf, "huber %g", k.scale); return buf;
    case RobustLoss::kCauchy: std::snprintf(buf, sizeof buf, "cauchy %g", k.scale); return buf;
  }
  return "none";
}

// Scores a solution against the truth: after a rigid fit of the whole map, and in the world
// frame when the map is in it.
void Score(const ReferenceInput& in, bool world_frame, ReferenceMap* m) {
  const LandmarkMap& map = m->solution.map;
  m->landmarks = static_cast<int>(map.size());
  const MapQuality fitted = EvaluateFittedMap(map, in.landmark_truth, in.seen, Pose2{});
  m->evaluated = fitted.evaluated;
  if (!fitted.evaluated) return;
  m->matched = fitted.matched;
  m->rmse_aligned_m = fitted.rmse_m;
  m->nees_mean = fitted.nees_mean;
  m->consistent_ratio = fitted.consistent_ratio;
  if (world_frame) {
    const MapQuality world = EvaluateMap(map, in.landmark_truth, in.seen);
    m->rmse_m = world.rmse_m;
    m->nees_mean = world.nees_mean;
    m->consistent_ratio = world.consistent_ratio;
  }
}

}  // namespace

ReferenceInput ReadReferenceInput(const Scenario& scenario, const std::string& datasets_root) {
  Scenario sc = scenario;
  // Known association: the simulator's identities, or the dataset's barcodes, whether or not
  // the agents are given them (the draws of the simulator do not depend on it).
  for (RobotSpec& r : sc.robots) r.sensor.signatures = true;
  Feed feed = MakeFeed(sc, datasets_root);
  ReferenceInput in;
  std::map<RobotId, std::unique_ptr<LogSink>> sinks;
  std::map<RobotId, std::optional<Pose2>> starts;
  for (const auto& [id, start] : feed.source->Truth().starts) starts[id] = start;
  for (const RobotSpec& r : sc.robots) {
    const AgentRun run = AgentRunFor(sc, r.id);
    const LocalSlamOptions o = sc.agent.slam.ForSensor(run.sensor);
    sinks[r.id] = std::make_unique<LogSink>(r.id, run.noise, o.min_range_m, o.max_range_m, starts[r.id]);
  }
  std::map<RobotId, double> first_stamp;  // where each robot's odometry starts
  while (!feed.source->Done()) {
    const FeedBatch b = feed.source->Next();
    for (const Scan& s : b.scans) sinks.at(s.robot_id)->sync().OnScan(s);
    for (const Odometry& o : b.odom) {
      first_stamp.try_emplace(o.robot_id, o.stamp - o.dt);
      sinks.at(o.robot_id)->sync().OnOdometry(o);
    }
    for (const GroundTruth& g : b.truth) in.truth[g.robot_id].push_back(g);
  }
  const WorldTruth& world = feed.source->Truth();
  in.headings_known = world.headings_known;
  in.landmark_truth = world.landmarks;
  for (std::size_t i = 0; i < world.seen.size(); ++i) {
    if (world.seen[i]) in.seen.push_back(static_cast<int>(i));
  }
  for (const auto& [id, sink] : sinks) {
    in.logs.push_back(sink->log());
    // Each true track from the start pose, so that a scan at the start finds its pose.
    auto& track = in.truth[id];
    const std::optional<Pose2>& start = starts[id];
    const auto t0 = first_stamp.find(id);
    if (start && t0 != first_stamp.end() && (track.empty() || track.front().stamp > t0->second + 1e-9)) {
      track.insert(track.begin(), GroundTruth{id, t0->second, start->x, start->y, start->theta});
    }
  }
  return in;
}

Reference ComputeReference(const Scenario& scenario, const ReferenceOptions& options) {
  const auto start = Clock::now();
  Reference ref;
  ReferenceInput in = ReadReferenceInput(scenario, options.datasets_root);
  ref.until = options.until;
  for (BatchRobotLog& log : in.logs) {
    const auto until = options.until.find(log.robot);
    if (until == options.until.end()) continue;
    // Node 0 (where the odometry starts) stays, its scan only within the time; each later node is
    // a scan, in time order.
    if (log.nodes.empty()) continue;
    if (!(log.nodes.front().stamp <= until->second + 1e-9)) log.nodes.front().obs.clear();
    log.nodes.erase(std::find_if(log.nodes.begin() + 1, log.nodes.end(),
                                 [&](const BatchNode& n) { return !(n.stamp <= until->second + 1e-9); }),
                    log.nodes.end());
  }
  ref.landmark_truth = in.landmark_truth;
  ref.seen = in.seen;
  std::size_t observations = 0;
  for (const BatchRobotLog& log : in.logs) observations += log.Observations();
  if (in.landmark_truth.empty()) {
    ref.why_none = "no landmark truth to score against";
    ref.total_s = Since(start);
    return ref;
  }
  if (observations == 0) {
    ref.why_none = "no known association: the data carries no landmark identities";
    ref.total_s = Since(start);
    return ref;
  }
  BatchOptions batch;
  batch.robust = options.robust.value_or(scenario.source.IsDataset() ? RobustKernel{RobustLoss::kCauchy, 2.0}
                                                                     : RobustKernel{});
  ref.loss = Describe(batch.robust);
  ref.available = true;

  std::vector<BatchSolution> singles;
  for (const BatchRobotLog& log : in.logs) {
    const auto t = Clock::now();
    ReferenceMap m;
    m.solution = SolveSingleRobotBatch(log, batch);
    m.solve_s = Since(t);
    Score(in, log.start.has_value(), &m);
    singles.push_back(m.solution);
    ref.own[log.robot] = std::move(m);
  }
  const auto t = Clock::now();
  ref.central.solution = SolveCentralBatch(in.logs, singles, batch);
  ref.central.solve_s = Since(t);
  // Any robot's true start fixes the central map in the world frame.
  const bool any_start = std::any_of(in.logs.begin(), in.logs.end(),
                                     [](const BatchRobotLog& l) { return l.start.has_value(); });
  Score(in, any_start, &ref.central);

  const bool truth_poses = in.headings_known && std::any_of(in.truth.begin(), in.truth.end(),
                                                            [](const auto& t) { return !t.second.empty(); });
  if (!options.known_pose) {
    ref.known_pose_why_none = "not asked for";
  } else if (!truth_poses) {
    ref.known_pose_why_none = "no robot ground truth with headings";
  } else {
    const BatchTruePose true_pose = [&](RobotId robot, double stamp) -> std::optional<Pose2> {
      const auto it = in.truth.find(robot);
      // Only within the true track (TruthAt would clamp at its ends).
      if (it == in.truth.end() || it->second.empty() || std::isnan(stamp) || stamp < it->second.front().stamp - 1e-9 ||
          stamp > it->second.back().stamp + 1e-9) {
        return std::nullopt;
      }
      return TruthAt(it->second, stamp);
    };
    const auto tk = Clock::now();
    ReferenceMap m;
    m.solution = SolveKnownPoseMap(in.logs, true_pose, batch);
    m.solve_s = Since(tk);
    Score(in, true, &m);
    ref.known_pose = std::move(m);
    for (const BatchRobotLog& log : in.logs) {
      const auto tr = Clock::now();
      ReferenceMap own;
      own.solution = SolveKnownPoseMap({log}, true_pose, batch);
      own.solve_s = Since(tr);
      Score(in, true, &own);
      ref.own_known_pose[log.robot] = std::move(own);
    }
  }
  ref.total_s = Since(start);
  return ref;
}

}  // namespace mapmesh::lab
