#include "agent/agent_setup.h"

#include <cmath>
#include <limits>

#include "common/check.h"

namespace mapmesh {

AgentRun AgentRunFor(const Scenario& sc, RobotId self) {
  const RobotSpec* robot = sc.FindRobot(self);
  MAPMESH_CHECK(robot != nullptr, "agent id not in the scenario");
  AgentRun run;
  for (const RobotSpec& r : sc.robots) run.robots.push_back(r.id);
  run.seed = sc.seed;
  // A dataset replayed whole ends where its data does, which the agent does not read.
  run.end_s = sc.source.IsDataset() && !sc.duration_given ? std::numeric_limits<double>::infinity() : sc.duration_s;
  run.trajectory_period_s = sc.feeder.truth_period_s;
  run.loss_probability = sc.radio.loss_probability;
  run.bandwidth_bytes_per_s = sc.radio.bandwidth_bytes_per_s;
  run.latency_s = sc.radio.latency_s;
  run.latency_jitter_s = sc.radio.latency_jitter_s;
  run.exchange_ticks = sc.feeder.pace == Pace::kLockstep;

  const MotionModel motion = MotionModelFor(robot->motion);
  run.noise.motion = motion;
  const double sigma_turn = motion.kind == MotionModel::Kind::kAckermann ? robot->motion.sigma_steering_rad
                                                                         : robot->motion.sigma_w_radps;
  run.noise.control_cov = Eigen::Vector2d(std::pow(robot->motion.sigma_v_mps, 2), sigma_turn * sigma_turn).asDiagonal();
  run.noise.control_period_s = sc.world.control_period_s;
  run.noise.obs_cov = Eigen::Vector2d(std::pow(robot->sensor.sigma_range_m, 2),
                                      std::pow(DegToRad(robot->sensor.sigma_bearing_deg), 2))
                          .asDiagonal();
  run.sensor.max_range_m = robot->sensor.max_range_m;
  run.sensor.sigma_range_m = robot->sensor.sigma_range_m;
  run.sensor.sigma_bearing_rad = DegToRad(robot->sensor.sigma_bearing_deg);
  run.sensor.signatures = robot->sensor.signatures;
  return run;
}

std::unique_ptr<LocalMapper> MakeLocalMapper(const Scenario& sc, RobotId self) {
  const AgentRun run = AgentRunFor(sc, self);
  return MakeLocalMapper(sc.agent, run.noise, run.sensor);
}

}  // namespace mapmesh
