#include "sim_feeder/simulator.h"

#include <cmath>

#include "sim_feeder/radio_model.h"

namespace mapmesh {

Simulator::Simulator(const Scenario& scenario, World world)
    : scenario_(scenario), radio_(scenario.radio, scenario.seed), dt_(scenario.world.control_period_s) {
  for (RobotSpec& spec : scenario_.robots) {
    if (spec.path.type != PathType::kPark || world.paths.empty()) continue;
    const Polyline& line = world.paths[spec.path.index % world.paths.size()];
    spec.path.points.assign(line.begin() + 1, line.end());
    spec.path.points.insert(spec.path.points.end(), line.rbegin() + 1, line.rend());
    if (!spec.start_given) {
      const Eigen::Vector2d d = line[1] - line[0];
      spec.start = {line[0].x(), line[0].y(), std::atan2(d.y(), d.x())};
    }
  }
  truth_.landmarks = std::move(world.landmarks);
  truth_.seen.assign(truth_.landmarks.size(), false);
  last_step_ = static_cast<std::uint64_t>(std::floor(scenario_.duration_s / dt_ + 1e-9));
  robots_.reserve(scenario_.robots.size());
  for (const RobotSpec& spec : scenario_.robots) {
    Robot r{&spec,
            spec.start,
            {},
            std::mt19937_64(scenario_.seed * 6364136223846793005ULL + spec.id),
            std::mt19937_64(scenario_.seed * 1442695040888963407ULL + spec.id * 2862933555777941757ULL + 1)};
    robots_.push_back(std::move(r));
    truth_.starts.emplace_back(spec.id, spec.start);
  }
}

bool Simulator::Done() const { return step_ > last_step_; }

RadioLinks Simulator::Links(double stamp) const {
  std::vector<RobotPosition> pos;
  for (const Robot& r : robots_) pos.push_back({r.spec->id, r.pose.x, r.pose.y});
  return {stamp, radio_.Links(pos, stamp)};
}

Scan Simulator::Sense(Robot& r, double stamp) {
  Scan s;
  s.robot_id = r.spec->id;
  s.seq = r.scan_seq++;
  s.stamp = stamp;
  seen_scratch_.clear();
  s.obs = SenseLandmarks(r.pose, truth_.landmarks, r.spec->sensor, r.rng, &seen_scratch_);
  for (int i : seen_scratch_) truth_.seen[i] = true;
  return s;
}

void Simulator::SenseRobots(std::vector<Scan>& scans, std::size_t first) {
  std::normal_distribution<double> n01(0.0, 1.0);
  for (std::size_t k = first; k < scans.size(); ++k) {
    Scan& s = scans[k];
    Robot* me = nullptr;
    for (Robot& r : robots_) {
      if (r.spec->id == s.robot_id) me = &r;
    }
    if (me == nullptr || !me->spec->sensor.sees_robots) continue;
    const SensorOptions& sensor = me->spec->sensor;
    for (const Robot& other : robots_) {
      if (&other == me) continue;
      const Eigen::Vector2d at(other.pose.x, other.pose.y);
      if (!IsVisible(me->pose, at, sensor)) continue;
      Observation o = RangeBearing(me->pose, at);
      AddSensorNoise(o, sensor, n01, me->sight_rng);
      o.signature = static_cast<std::int32_t>(other.spec->id);
      o.kind = ObservationKind::kRobot;
      s.obs.push_back(o);
    }
  }
}

FeedBatch Simulator::Next() {
  FeedBatch b;
  const std::uint64_t k = step_++;
  b.stamp = static_cast<double>(k) * dt_;
  if (k == 0) {
    for (Robot& r : robots_) {
      if (!r.spec->sensor.scan_at_start) continue;
      b.scans.push_back(Sense(r, b.stamp));
      r.start_scans = 1;
    }
  } else {
    std::normal_distribution<double> n01(0.0, 1.0);
    for (Robot& r : robots_) {
      const RobotSpec& spec = *r.spec;
      const UnicycleControl u = FollowWaypoints(r.pose, spec.path, spec.motion, dt_, r.follower);
      r.pose = UnicycleMotion(r.pose, u, dt_);
      r.sum_v += u.v_mps + spec.motion.sigma_v_mps * n01(r.rng);
      r.sum_w += u.w_radps + spec.motion.sigma_w_radps * n01(r.rng);
      ++r.steps;
      // The first interval also carries the scan from the start pose (at its opening stamp).
      r.scans += r.start_scans;
      r.start_scans = 0;
      if (k % static_cast<std::uint64_t>(spec.sensor.scan_every_steps) == 0) {
        b.scans.push_back(Sense(r, b.stamp));
        ++r.scans;
      }
      if (r.steps < spec.motion.odometry_every_steps && k < last_step_) continue;
      Odometry o;
      o.robot_id = spec.id;
      o.seq = r.odom_seq++;
      o.stamp = b.stamp;
      o.dt = dt_ * r.steps;
      o.v = r.sum_v / r.steps;
      o.w = r.sum_w / r.steps;
      o.scans_in_interval = r.scans;
      b.odom.push_back(o);
      r.steps = 0;
      r.sum_v = r.sum_w = 0.0;
      r.scans = 0;
    }
  }
  // Every robot has moved: the scans of this step see the others where they are now.
  SenseRobots(b.scans, 0);
  for (const Robot& r : robots_) {
    b.truth.push_back({r.spec->id, b.stamp, r.pose.x, r.pose.y, r.pose.theta});
  }
  if (b.stamp + 1e-9 >= next_links_s_) {
    b.links = Links(b.stamp);
    next_links_s_ += scenario_.radio.links_period_s;
  }
  return b;
}

}  // namespace mapmesh
