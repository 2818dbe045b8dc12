#pragma once
// Topic names and QoS of every mapmesh topic, in one place (see ARCHITECTURE.md).
// Odometry and scans use one topic per robot, so an agent receives only its own streams.

#include <string>

#include "common/transport/dds.h"
#include "common/types/messages.h"

namespace mapmesh::transport {

inline std::string OdomTopic(RobotId id) { return "mapmesh/odom/" + std::to_string(id); }
inline std::string ScanTopic(RobotId id) { return "mapmesh/scan/" + std::to_string(id); }
inline constexpr const char* kLinksTopic = "mapmesh/links";
inline constexpr const char* kTruthTopic = "mapmesh/truth";
inline constexpr const char* kMapTopic = "mapmesh/map";
inline constexpr const char* kStatusTopic = "mapmesh/status";

// Liveliness lease of agent writers: a dead agent is noticed after about this long.
inline constexpr double kAgentLeaseS = 1.0;

// Sensor streams: reliable, keep-all, so that nothing is dropped at any pace.
inline Qos SensorQos() { return Qos().Reliable().KeepAll().Volatile(); }
// Link table: only the latest matters; late joiners get it.
inline Qos LinksQos() { return Qos().Reliable().KeepLast(1).TransientLocal(); }
inline Qos TruthQos() { return Qos().BestEffort().KeepLast(1); }
// Maps: latest per (robot, kind), kept for late joiners, liveliness tracks the sender.
inline Qos MapQos() { return Qos().Reliable().KeepLast(1).TransientLocal().Liveliness(kAgentLeaseS).NoAutoDispose(); }
inline Qos StatusQos() { return Qos().BestEffort().KeepLast(1).Liveliness(kAgentLeaseS); }

}  // namespace mapmesh::transport
