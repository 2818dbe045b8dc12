#include "sim_feeder/robot_sim.h"

#include <algorithm>
#include <cmath>

namespace mapmesh {

UnicycleControl FollowWaypoints(const Pose2& pose, const PathOptions& path, const MotionOptions& motion, double dt,
                                FollowerState& state) {
  if (state.finished || path.points.empty()) return {0.0, 0.0};
  // Switch waypoints inside the radius (possibly several, if they are close together).
  for (std::size_t guard = 0; guard <= path.points.size(); ++guard) {
    const Eigen::Vector2d d = path.points[state.next] - Eigen::Vector2d(pose.x, pose.y);
    if (d.norm() > motion.waypoint_radius_m) break;
    if (state.next + 1 < path.points.size()) {
      ++state.next;
    } else if (path.loop) {
      state.next = 0;
    } else {
      state.finished = true;
      return {0.0, 0.0};
    }
  }
  const Eigen::Vector2d d = path.points[state.next] - Eigen::Vector2d(pose.x, pose.y);
  const double error = WrapAngle(std::atan2(d.y(), d.x()) - pose.theta);
  const double w_max = DegToRad(motion.max_turn_rate_dps);
  if (motion.steering == Steering::kThesis) {
    // Thesis Fig. 27: turn at the maximum rate while the heading change needed exceeds what
    // one step at that rate gives, otherwise do not turn; the forward speed never changes.
    const double w = std::abs(error) > w_max * dt ? std::copysign(w_max, error) : 0.0;
    return {motion.speed_mps, w};
  }
  // Smooth: close the heading error as fast as the limit allows; turn in place when the
  // waypoint is behind.
  const double w = std::clamp(error / dt, -w_max, w_max);
  const double v = std::abs(error) > std::numbers::pi / 2 ? 0.0 : motion.speed_mps;
  return {v, w};
}

bool IsVisible(const Pose2& pose, const Eigen::Vector2d& landmark, const SensorOptions& sensor) {
  const double dx = landmark.x() - pose.x, dy = landmark.y() - pose.y;
  const double r = sensor.max_range_m;
  // Bounding box test (thesis 4.1.4.1).
  if (std::abs(dx) > r || std::abs(dy) > r) return false;
  // Bounding line test (4.1.4.2): in front of the robot, for fields of view up to 180 deg.
  if (sensor.fov_deg <= 180.0 && dx * std::cos(pose.theta) + dy * std::sin(pose.theta) <= 0.0) {
    return false;
  }
  // Bounding circle test (4.1.4.3).
  if (dx * dx + dy * dy > r * r) return false;
  // Narrower fields of view.
  if (sensor.fov_deg < 180.0) {
    const double bearing = WrapAngle(std::atan2(dy, dx) - pose.theta);
    if (std::abs(bearing) > DegToRad(sensor.fov_deg) / 2) return false;
  }
  return true;
}

Observation RangeBearing(const Pose2& pose, const Eigen::Vector2d& point) {
  const double dx = point.x() - pose.x, dy = point.y() - pose.y;
  Observation o;
  o.range = std::sqrt(dx * dx + dy * dy);
  o.bearing = WrapAngle(std::atan2(dy, dx) - pose.theta);
  return o;
}

void AddSensorNoise(Observation& o, const SensorOptions& sensor, std::normal_distribution<double>& n01,
                    std::mt19937_64& rng) {
  o.range = std::max(0.0, o.range + sensor.sigma_range_m * n01(rng));
  o.bearing = WrapAngle(o.bearing + DegToRad(sensor.sigma_bearing_deg) * n01(rng));
}

std::vector<Observation> SenseLandmarks(const Pose2& pose, const std::vector<Eigen::Vector2d>& landmarks,
                                        const SensorOptions& sensor, std::mt19937_64& rng, std::vector<int>* indices) {
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<Observation> out;
  for (std::size_t i = 0; i < landmarks.size(); ++i) {
    if (!IsVisible(pose, landmarks[i], sensor)) continue;
    Observation o = RangeBearing(pose, landmarks[i]);
    AddSensorNoise(o, sensor, n01, rng);
    o.signature = sensor.signatures ? static_cast<std::int32_t>(i) : -1;
    o.kind = ObservationKind::kLandmark;
    out.push_back(o);
    if (indices) indices->push_back(static_cast<int>(i));
  }
  return out;
}

}  // namespace mapmesh
