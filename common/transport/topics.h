#pragma once
// Topic names and QoS of every mapmesh topic, in one place (see ARCHITECTURE.md).
// Odometry and scans use one topic per robot, so an agent receives only its own streams.

#include <string>
#include <vector>

#include "common/transport/dds.h"
#include "common/transport/feeder_source.h"
#include "common/types/messages.h"

namespace mapmesh::transport {

inline std::string OdomTopic(RobotId id) { return "mapmesh/odom/" + std::to_string(id); }
inline std::string ScanTopic(RobotId id) { return "mapmesh/scan/" + std::to_string(id); }
inline constexpr const char* kLinksTopic = "mapmesh/links";
inline constexpr const char* kTruthTopic = "mapmesh/truth";
inline constexpr const char* kMapTopic = "mapmesh/map";
inline constexpr const char* kStatusTopic = "mapmesh/status";
inline constexpr const char* kSightingTopic = "mapmesh/sighting";
inline constexpr const char* kTickTopic = "mapmesh/tick";

// Each agent writes its maps, status and sightings in the DDS partition of its robot,
// "robot<id>", and readers read every such partition. A sample whose robot id is not its
// writer's partition's is refused (SpeaksFor): under DDS Security (scripts/swarm run --secure)
// a participant's permissions allow it only its own robot's partition, so no peer can publish
// as another robot.
inline std::string RobotPartition(RobotId id) { return "robot" + std::to_string(id); }
inline constexpr const char* kEveryRobotPartition = "robot*";
// Whether a writer with these partitions may speak for robot id: its only partition is id's.
inline bool SpeaksFor(const std::vector<std::string>* writer_partitions, RobotId id) {
  return writer_partitions && writer_partitions->size() == 1 && writer_partitions->front() == RobotPartition(id);
}

// The feeder writes link tables and exchange ticks in its own partition (kFeederPartition,
// feeder_source.h); agents read them from every partition, the default one included, so that a
// table or tick from anyone else is seen, refused and counted (FeederSource). Those readers keep
// every sample until taken (history is not a matched policy), so that nobody else's samples
// can push the feeder's out of a reader's history before it is taken.
inline Qos FeederWriter(Qos q) { return q.Partition(kFeederPartition); }
inline Qos FeederTopicReader(Qos q) { return q.KeepAll().Partitions({"", "*"}); }

// The agents' map and status writers have a liveliness lease (AgentOptions::LivelinessLeaseS):
// a dead agent is noticed after about that long. Writer and readers must use the same one.

// Sensor streams: reliable, keep-all, so that nothing is dropped at any pace.
inline Qos SensorQos() { return Qos().Reliable().KeepAll().Volatile(); }
// Link table: only the latest matters; late joiners get it.
inline Qos LinksQos() { return Qos().Reliable().KeepLast(1).TransientLocal(); }
inline Qos TruthQos() { return Qos().BestEffort().KeepLast(1); }
// Maps: latest per (robot, kind), liveliness tracks the sender. Best-effort: every map is
// superseded by the sender's next one a period later, and a reliable map topic cost a swarm of
// 64 agents a fifth of its CPU in heartbeats and acknowledgements (docs/BENCHMARKS.md); for the
// same reason a late joiner gets each peer's next map, not the last one sent.
inline Qos MapQos(double lease_s) {
  return Qos().BestEffort().KeepLast(1).Volatile().Liveliness(lease_s).NoAutoDispose();
}
// In lockstep the maps are exchanged at ticks (ExchangeTick) and each must arrive before the
// next tick: reliable, every sample kept until taken (a forged map claiming a robot must not
// overtake that robot's genuine one in a reader's cache); transient-local, so that a reader
// matched late (a restarted agent, a participant back from a long pause) still gets each peer's
// latest maps, which are the tick's (the next go out only once every agent holds these).
inline Qos LockstepMapQos(double lease_s) {
  return Qos().Reliable().KeepAll().TransientLocal().Liveliness(lease_s).NoAutoDispose();
}
// The map topic's QoS for a run's pace (every reader and writer of one run must agree).
inline Qos MapQosFor(bool lockstep, double lease_s) { return lockstep ? LockstepMapQos(lease_s) : MapQos(lease_s); }
// Robot sightings and their answers, realtime pace only: rare (at most one per peer and
// agent.rendezvous_period_s), each one useful on its own; best-effort like the maps, a few kept
// per publisher. In lockstep they ride on the tick's maps (MapMessage::sightings) and this topic
// is not used: a topic of their own, reliable, cost 64 agents more CPU than all of rendezvous's
// computing (docs/BENCHMARKS.md).
inline Qos SightingQos() { return Qos().BestEffort().KeepLast(16).Volatile(); }
// Exchange ticks, feeder to agents: every one matters until the next; a late joiner gets the
// latest (the feeder sends the next only once every live agent has answered this one).
inline Qos TickQos() { return Qos().Reliable().KeepLast(1).TransientLocal(); }
inline Qos StatusQos(double lease_s) { return Qos().BestEffort().KeepLast(1).Liveliness(lease_s); }

}  // namespace mapmesh::transport
