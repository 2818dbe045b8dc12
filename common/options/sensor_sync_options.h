#pragma once
// SensorSyncOptions: when an agent's map frame is fixed, and which stamps it takes as plausible
// (agent/sensor_sync.h).

#include <limits>

namespace mapmesh {

struct SensorSyncOptions {
  bool frame_at_first_landmark = true;  // agent.frame_at_first_landmark: the map frame is the pose at the
                                        // first landmark mapped (agent/sensor_sync.h)
  double max_stamp_jump_s = 20.0;       // stamps this far beyond the odometry received so far are implausible
  double max_stamp_s = std::numeric_limits<double>::infinity();  // and any beyond this (the run's end)

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md); the stamp bounds
  // are the agent's (AgentOptions).
  template <typename Reader>
  void Read(Reader& r) {
    r.Get("frame_at_first_landmark", frame_at_first_landmark);
  }
};

}  // namespace mapmesh
