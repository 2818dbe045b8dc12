#pragma once
// One simulated robot's pieces: the waypoint follower (thesis Fig. 27) and the
// LMS-200-like range-bearing sensor with the visibility tests of thesis 4.1.4.

#include <Eigen/Core>
#include <random>
#include <vector>

#include "common/config/scenario.h"
#include "common/geometry/pose2.h"
#include "common/slam/motion_model.h"
#include "common/types/messages.h"

namespace mapmesh {

// Progress along a path.
struct FollowerState {
  std::size_t next = 0;   // index of the waypoint being approached
  bool finished = false;  // a non-looping path was completed: the robot stands still
};

// The control that steers `pose` toward the next waypoint, switching to the following one
// inside the waypoint radius. steering "thesis" (Fig. 27): full turn rate toward the
// waypoint, or none once within one step of it, at constant speed. "smooth": turn rate
// proportional to the error up to the limit, turning in place when the waypoint is behind.
UnicycleControl FollowWaypoints(const Pose2& pose, const PathOptions& path, const MotionOptions& motion, double dt,
                                FollowerState& state);

// Thesis 4.1.4: bounding box, bounding line (in front of the robot) and bounding circle
// tests, then the field of view when it is narrower than 180 degrees.
bool IsVisible(const Pose2& pose, const Eigen::Vector2d& landmark, const SensorOptions& sensor);

// Noise-free range and bearing to a point (thesis eq. 100).
Observation RangeBearing(const Pose2& pose, const Eigen::Vector2d& point);

// o with the sensor's Gaussian range and bearing noise added (range first, then bearing), drawn
// with n01 (a standard normal kept across calls: it caches every second draw) from rng.
void AddSensorNoise(Observation& o, const SensorOptions& sensor, std::normal_distribution<double>& n01,
                    std::mt19937_64& rng);

// Observations of every visible landmark, with Gaussian range and bearing noise.
// Signatures are the landmark indices when sensor.signatures is set, else -1. When
// indices is given, the index of each observed landmark is appended to it.
std::vector<Observation> SenseLandmarks(const Pose2& pose, const std::vector<Eigen::Vector2d>& landmarks,
                                        const SensorOptions& sensor, std::mt19937_64& rng,
                                        std::vector<int>* indices = nullptr);

}  // namespace mapmesh
