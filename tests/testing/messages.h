#pragma once
// Minimal messages for tests: the fields that identify them, everything else default.

#include "common/types/messages.h"

namespace mapmesh::testing {

inline Odometry OdometryAt(RobotId id, double stamp) {
  Odometry o;
  o.robot_id = id;
  o.stamp = stamp;
  return o;
}

inline Scan ScanAt(RobotId id, double stamp) {
  Scan s;
  s.robot_id = id;
  s.stamp = stamp;
  return s;
}

inline AgentStatus StatusAt(RobotId id, std::uint32_t incarnation, double processed_until) {
  AgentStatus s;
  s.robot_id = id;
  s.incarnation = incarnation;
  s.processed_until = processed_until;
  return s;
}

}  // namespace mapmesh::testing
