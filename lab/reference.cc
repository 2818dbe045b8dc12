#include "lab/reference.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <future>
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

// Runs f(0), ..., f(n - 1) on two threads (this one and one more): for independent solves, whose
// results do not depend on the order. An exception in either reaches the caller.
template <typename F>
void TwoAtATime(std::size_t n, F f) {
  std::future<void> odd = std::async(std::launch::async, [&] {
    for (std::size_t i = 1; i < n; i += 2) f(i);
  });
  std::exception_ptr error;
  try {
    for (std::size_t i = 0; i < n; i += 2) f(i);
  } catch (...) {
    error = std::current_exception();
  }
  odd.get();
  if (error) std::rethrow_exception(error);
}

// A robot's streams in time order, through the agent's own SensorSync (so the intervals are
// split at the scans exactly as the agent splits them), recorded to be replayed into its batch
// log once every robot's sightings are known; odometry from the start (the frame is the start
// pose, not the first landmark's).
class StreamRecorder : public SensorSync::Sink {
 public:
  struct Event {
    OdometryControl u;
    double dt = 0.0;
    int scan = -1;  // >= 0: this scan of scans(), applied at its stamp
  };
  StreamRecorder() : sync_(*this, false) {}
  void Move(const OdometryControl& u, double dt) override { events_.push_back({u, dt, -1}); }
  void ApplyScan(const Scan& scan, double stamp) override {
    events_.push_back({{}, 0.0, static_cast<int>(scans_.size())});
    scans_.emplace_back(stamp, scan.obs);
  }
  void IntervalDone(const Odometry&) override {}
  bool Mapped() const override { return true; }
  SensorSync& sync() { return sync_; }
  const std::vector<Event>& events() const { return events_; }
  const std::vector<std::pair<double, std::vector<Observation>>>& scans() const { return scans_; }

 private:
  std::vector<Event> events_;
  std::vector<std::pair<double, std::vector<Observation>>> scans_;
  SensorSync sync_;
};

// Two times this close are one (s): a sighting's stamp and the scan or odometry end it falls on.
constexpr double kSameTimeS = 1e-6;

// Replays a recorded stream from time t0 into a batch log, with a node at each of `marks`
// (increasing times at which a sighting needs the robot's pose): an odometry interval is split
// there, the robot moved to the mark under the same control. Returns the node of each mark, -1
// for one outside the stream.
std::vector<int> Replay(const StreamRecorder& rec, double t0, const std::vector<double>& marks,
                        BatchLogBuilder* builder) {
  std::vector<int> nodes(marks.size(), -1);
  std::size_t m = 0;
  while (m < marks.size() && marks[m] < t0 - kSameTimeS) ++m;  // before the stream: no pose
  double t = t0;
  for (const StreamRecorder::Event& e : rec.events()) {
    if (e.scan >= 0) {
      const auto& [ts, obs] = rec.scans()[static_cast<std::size_t>(e.scan)];
      for (; m < marks.size() && marks[m] < ts - kSameTimeS; ++m) nodes[m] = builder->Mark(t);
      builder->Scan(ts, obs);
      t = ts;
      for (; m < marks.size() && marks[m] <= ts + kSameTimeS; ++m) nodes[m] = builder->Mark(ts);
      continue;
    }
    const double end = t + e.dt;
    for (; m < marks.size() && marks[m] <= end + kSameTimeS; ++m) {
      if (marks[m] > t + kSameTimeS) {
        builder->Move(e.u, marks[m] - t);
        t = marks[m];
      }
      nodes[m] = builder->Mark(t);
    }
    if (end - t > kSameTimeS) builder->Move(e.u, end - t);
    t = std::max(t, end);
  }
  for (; m < marks.size() && marks[m] <= t + kSameTimeS; ++m) nodes[m] = builder->Mark(t);
  return nodes;
}

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
// A centralized solution of several components is fitted component by component.
void Score(const ReferenceInput& in, bool world_frame, ReferenceMap* m) {
  const LandmarkMap& map = m->solution.map;
  m->landmarks = static_cast<int>(map.size());
  const MapQuality fitted = EvaluateFittedParts(map, m->solution.landmark_component, in.landmark_truth, in.seen,
                                                Pose2{});
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
  std::map<RobotId, std::unique_ptr<StreamRecorder>> sinks;
  std::map<RobotId, std::optional<Pose2>> starts;
  for (const auto& [id, start] : feed.source->Truth().starts) starts[id] = start;
  for (const RobotSpec& r : sc.robots) sinks[r.id] = std::make_unique<StreamRecorder>();
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
  // The sightings the agents use (agent.align_by with rendezvous), as their RendezvousTracker
  // takes them: a robot of the run other than the observer, at most one of each peer every
  // rendezvous_period_s, in the observer's time order.
  struct Seen {
    RobotId robot, other;
    double stamp;
    Eigen::Vector2d z;
  };
  std::vector<Seen> seen;
  std::map<RobotId, std::vector<double>> marks;
  if (sc.agent.exchange.ByRendezvous()) {
    for (const auto& [id, sink] : sinks) {
      std::map<RobotId, double> last;
      for (const auto& [ts, obs] : sink->scans()) {
        for (const Observation& o : obs) {
          if (o.kind != ObservationKind::kRobot || o.signature < 0 || !IsValidObservation(o)) continue;
          const RobotId other = static_cast<RobotId>(o.signature);
          if (other == id || !sinks.contains(other)) continue;
          const auto l = last.find(other);
          if (l != last.end() && ts - l->second < sc.agent.rendezvous.period_s - 1e-9) continue;
          last[other] = ts;
          seen.push_back({id, other, ts, {o.range, o.bearing}});
          marks[id].push_back(ts);
          marks[other].push_back(ts);
        }
      }
    }
  }
  std::map<RobotId, std::map<double, int>> node_at;  // each robot's node at each of its marks
  std::map<RobotId, Eigen::Matrix2d> sighting_cov;
  for (const auto& [id, sink] : sinks) {
    const AgentRun run = AgentRunFor(sc, id);
    const LocalSlamOptions o = sc.agent.slam.ForSensor(run.sensor);
    BatchLogBuilder builder(id, run.noise, o.min_range_m, o.max_range_m, starts[id]);
    std::vector<double>& m = marks[id];
    std::sort(m.begin(), m.end());
    m.erase(std::unique(m.begin(), m.end()), m.end());
    const auto t0 = first_stamp.find(id);
    const std::vector<int> nodes = Replay(*sink, t0 != first_stamp.end() ? t0->second : 0.0, m, &builder);
    for (std::size_t k = 0; k < m.size(); ++k) node_at[id][m[k]] = nodes[k];
    sighting_cov[id] = Eigen::Vector2d(run.sensor.sigma_range_m * run.sensor.sigma_range_m,
                                       run.sensor.sigma_bearing_rad * run.sensor.sigma_bearing_rad)
                           .asDiagonal();
    in.logs.push_back(builder.log());
  }
  for (const Seen& v : seen) {
    const int a = node_at[v.robot][v.stamp], b = node_at[v.other][v.stamp];
    if (a < 0 || b < 0) {
      ++in.sightings_without_pose;
      continue;
    }
    in.sightings.push_back({v.robot, a, v.other, b, v.stamp, v.z, sighting_cov[v.robot]});
  }
  for (const auto& [id, sink] : sinks) {
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

  // The solves are independent of each other: two at a time (the results do not depend on it).
  std::vector<ReferenceMap> own(in.logs.size());
  TwoAtATime(in.logs.size(), [&](std::size_t r) {
    const auto t = Clock::now();
    own[r].solution = SolveSingleRobotBatch(in.logs[r], batch);
    own[r].solve_s = Since(t);
    Score(in, in.logs[r].start.has_value(), &own[r]);
  });
  std::vector<BatchSolution> singles;
  for (std::size_t r = 0; r < in.logs.size(); ++r) {
    singles.push_back(own[r].solution);
    ref.own[in.logs[r].robot] = std::move(own[r]);
  }
  // A sighting is its observer's data at its time and needs the other robot's pose then: both
  // robots' data must reach that far.
  std::erase_if(in.sightings, [&](const BatchSighting& v) {
    for (RobotId r : {v.robot, v.other}) {
      const auto until = options.until.find(r);
      if (until != options.until.end() && !(v.stamp <= until->second + 1e-9)) return true;
    }
    return false;
  });
  // A component is in the world frame when its gauge's start is the true one.
  auto in_world = [](const BatchSolution& s) {
    return !s.components.empty() &&
           std::all_of(s.components.begin(), s.components.end(), [](const BatchComponent& c) { return c.in_world; });
  };
  // The fair optimum and the known-starts one, both from the robots' own solutions, side by side;
  // one problem when no robot's start is known but the first one's (the fair gauge).
  const bool same = in.logs.size() <= 1 || std::none_of(in.logs.begin() + 1, in.logs.end(),
                                                        [](const BatchRobotLog& l) { return l.start.has_value(); });
  TwoAtATime(same || !options.known_starts ? 1 : 2, [&](std::size_t k) {
    const StartKnowledge starts = k == 0 ? StartKnowledge::kNone : StartKnowledge::kKnown;
    ReferenceMap& m = k == 0 ? ref.central : ref.central_known_starts;
    const auto t = Clock::now();
    m.solution = SolveCentralBatch(in.logs, singles, in.sightings, {batch, starts});
    m.solve_s = Since(t);
    Score(in, in_world(m.solution), &m);
  });
  if (same) ref.central_known_starts = ref.central;
  ref.has_known_starts = same || options.known_starts;
  if (options.check_start) {
    // The truth as a start: every node's true pose, every landmark's true position.
    CentralStart truth;
    bool complete = in.headings_known;
    for (const BatchRobotLog& log : in.logs) {
      const auto track = in.truth.find(log.robot);
      if (track == in.truth.end() || track->second.empty()) {
        complete = false;
        break;
      }
      std::vector<Pose2>& poses = truth.poses[log.robot];
      for (const BatchNode& node : log.nodes) {
        const std::optional<Pose2> at = std::isnan(node.stamp) ? log.start : TruthAt(track->second, node.stamp);
        complete = complete && at.has_value();
        poses.push_back(at.value_or(Pose2{}));
      }
    }
    for (std::size_t j = 0; j < in.landmark_truth.size(); ++j) {
      truth.landmarks[static_cast<std::int32_t>(j)] = in.landmark_truth[j];
    }
    if (complete && in_world(ref.central.solution)) {
      ref.central.from_truth = SolveCentralBatch(in.logs, singles, in.sightings, {batch, StartKnowledge::kNone}, &truth)
                                   .report;
    }
  }

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
