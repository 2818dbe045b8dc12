#pragma once
// Value types exchanged between the feeder, the agents and the launcher. They mirror
// idl/mapmesh.idl; transport/convert.h maps between the two.

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace mapmesh {

using RobotId = std::uint32_t;

// Odometry over (stamp - dt, stamp]. Unicycle robots use v and w, car-like robots v and
// steering. scans_in_interval tells the agent how many scans of this interval to wait for.
struct Odometry {
  RobotId robot_id = 0;
  std::uint32_t seq = 0;
  double stamp = 0.0;     // s, end of the interval
  double dt = 0.0;        // s, length of the interval
  double v = 0.0;         // m/s
  double w = 0.0;         // rad/s
  double steering = 0.0;  // rad
  std::uint32_t scans_in_interval = 0;
  bool sync = false;  // lockstep barrier: report status after processing this
};

enum class ObservationKind : std::uint8_t { kLandmark = 0, kRobot = 1 };

// One range-bearing reading in the sensor frame (bearing from the robot's heading).
struct Observation {
  double range = 0.0;           // m
  double bearing = 0.0;         // rad
  std::int32_t signature = -1;  // identity when the scenario shares it, else -1
  ObservationKind kind = ObservationKind::kLandmark;
};

struct Scan {
  RobotId robot_id = 0;
  std::uint32_t seq = 0;
  double stamp = 0.0;  // s
  std::vector<Observation> obs;
};

// The scan as the wire carries it (idl/mapmesh.idl): ranges and bearings as 32-bit floats. The
// in-process bus rounds its scans so, and its agents see exactly what a swarm's agents do. (The
// rounding goes through a volatile float: GCC 12 at -O2 drops a plain double-float-double cast
// in this loop.)
inline Scan AsOnTheWire(Scan s) {
  auto round = [](double v) {
    volatile float f = static_cast<float>(v);
    return static_cast<double>(f);
  };
  for (Observation& o : s.obs) {
    o.range = round(o.range);
    o.bearing = round(o.bearing);
  }
  return s;
}

// An unordered pair of robots that can hear each other; a < b.
struct Link {
  RobotId a = 0;
  RobotId b = 0;
  bool operator==(const Link&) const = default;
};

struct RadioLinks {
  double stamp = 0.0;
  std::vector<Link> links;
};

// True pose of a robot, for evaluation only.
struct GroundTruth {
  RobotId robot_id = 0;
  double stamp = 0.0;
  double x = 0.0, y = 0.0, theta = 0.0;
};

// Robots that see each other (thesis 3.3.1): an agent that sights a peer publishes the
// sighting with its own pose estimate then; the sighted peer answers with its pose estimate at
// that stamp. Each side then holds one point of the sighted robot in both map frames.
enum class SightingKind : std::uint8_t { kSighting = 0, kAnswer = 1 };

struct Sighting {
  RobotId robot_id = 0;           // the publisher
  std::uint32_t incarnation = 0;  // its process start: its map frame
  SightingKind kind = SightingKind::kSighting;
  RobotId other = 0;                     // the robot sighted; for an answer, the robot whose sighting it answers
  std::uint32_t other_incarnation = 0;   // answer: the incarnation that sighting came from
  double stamp = 0.0;                    // s, when the sighting was taken
  double x = 0.0, y = 0.0, theta = 0.0;  // the publisher's pose estimate in its map frame at stamp
  std::array<double, 6> cov{};           // its covariance: xx, xy, xt, yy, yt, tt
  double range = 0.0, bearing = 0.0;     // sighting: the measurement (m, rad)
  double sigma_range = 0.0, sigma_bearing = 0.0;  // sighting: the publisher's sensor noise (m, rad)
  std::uint32_t tick = 0;  // lockstep: the exchange tick it was published at (ExchangeTick); 0 otherwise
};

enum class MapKind : std::uint8_t { kLocal = 0, kGlobal = 1 };

// A map as it travels: the payload is the codec of common/map/map_codec.h.
// A chain of closed submaps an agent holds (issue J1): robot's incarnation's submaps 0 ..
// count - 1, without a gap. Advertised on every local map, so that peers send only what is
// missing (agent/submap_relay.h).
struct SubmapChain {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  std::uint32_t count = 0;
  // With fusion joining: the end (closed_s) of another robot's open submap the publisher holds
  // beyond the chain's closed ones (from that robot, or relayed once it fell silent); 0 when none.
  double open_until = 0.0;
  friend auto operator<=>(const SubmapChain&, const SubmapChain&) = default;
};

// Where the publisher's last join put another robot's submap chain (fusion joining, issue J1):
// the chain's first frame in the publisher's local frame. A peer that holds the chain only
// through relays composes it with where it put the publisher, instead of searching for it.
struct ChainPlacement {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  double x = 0.0, y = 0.0, theta = 0.0;  // m, m, rad
  friend auto operator<=>(const ChainPlacement&, const ChainPlacement&) = default;
};

// A submap as it travels (common/map/submap_codec.h) and, in a secure run, its origin's
// signature over those bytes (agent/submap_authority.h; empty in a plain run). Relays carry
// both unchanged: the bytes are the submap's identity's content, the signature its proof of
// origin (issue R3).
struct SubmapBlob {
  SubmapBlob() = default;
  // Bytes alone are an unsigned submap (a plain run's).
  SubmapBlob(std::vector<std::uint8_t> b, std::vector<std::uint8_t> s = {})  // NOLINT(google-explicit-constructor)
      : bytes(std::move(b)), signature(std::move(s)) {}
  std::vector<std::uint8_t> bytes;
  std::vector<std::uint8_t> signature;
  friend bool operator==(const SubmapBlob&, const SubmapBlob&) = default;
};

struct MapMessage {
  RobotId robot_id = 0;
  MapKind kind = MapKind::kLocal;
  std::uint32_t incarnation = 0;  // the sender's process start: each has its own map frame
  std::uint32_t version = 0;      // publications of this kind within the incarnation
  double stamp = 0.0;             // s, the sender's processed_until when it published
  double origin_stamp = 0.0;      // s, when the sender's map frame was fixed
  std::uint32_t tick = 0;         // lockstep: the exchange tick it was published at (ExchangeTick); 0 otherwise
  std::vector<std::uint8_t> payload;
  // Lockstep: the publisher's sightings and answers of the tick ride on one of its maps (the
  // local one), so that rendezvous costs no message of its own; each must be the publisher's.
  std::vector<Sighting> sightings;
  // Closed submaps (issue J1), on the local map only: the chains the publisher holds, and the
  // closed submaps it sends (its own or relayed, each the bytes of common/map/submap_codec.h).
  std::vector<SubmapChain> submaps_held;
  std::vector<SubmapBlob> submaps;
  // The digests (common/map/submap_digest.h) of the publisher's own closed submaps of this
  // incarnation, the latest of them: indices count - size .. count - 1, where count is its own
  // chain's in submaps_held (issue R3: a holder hearing the owner drops a copy that disagrees).
  std::vector<std::uint64_t> own_submap_digests;
  // With fusion joining: the publisher's open submap as it stands (the submap codec; its index
  // is the count of the publisher's closed ones, its closed_s the map's stamp). It changes at
  // every publication until it closes; a receiver keeps the latest.
  std::vector<std::uint8_t> open_submap;
  std::vector<std::uint8_t> open_submap_signature;  // secure runs: the publisher's signature of open_submap
  // With fusion joining, on the local map: where its last join put the other chains it joined,
  // in (robot, incarnation) order.
  std::vector<ChainPlacement> placements;
  // With fusion joining, on the local map: open submaps of other robots that fell silent, as
  // the publisher last took them, relayed to the peers that lack them (agent/submap_relay.h).
  std::vector<SubmapBlob> open_relayed;
};

// The lockstep exchange, from the feeder to the agents (feeder.pace lockstep). At each exchange
// point, once every agent has processed the sensor data up to it, the feeder sends a tick in
// two phases:
// - kExchange: each live agent listed applies, in a fixed order, the peers' messages of earlier
//   ticks, updates its global map, and publishes its maps and the sightings it held back, each
//   tagged with the tick; its status then reports the tick done and how many messages it
//   published.
// - kDeliver: each live agent reports the tick delivered once it holds every message the tick
//   lists (per publisher incarnation, how many it published at this tick).
// Peers' messages are thus applied at fixed points of scenario time in a fixed order, and
// delivered before the next: two runs of one scenario and seed exchange exactly the same.
enum class TickPhase : std::uint8_t { kExchange = 0, kDeliver = 1 };

struct TickPeer {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  std::uint32_t messages = 0;  // kDeliver: maps and sightings it published at this tick
  bool operator==(const TickPeer&) const = default;
};

struct ExchangeTick {
  std::uint32_t index = 0;  // 1, 2, ...: tick k is at the k-th exchange point (some may be skipped)
  double stamp = 0.0;       // s, the exchange point
  TickPhase phase = TickPhase::kExchange;
  RadioLinks links{-1.0, {}};   // kExchange: the link table current at the tick (stamp -1: none yet); the gates
                                // use it at the tick (a table on the links topic may be overtaken by another)
  std::vector<TickPeer> peers;  // every live agent, by robot
};

// What an agent has done so far.
struct AgentStatus {
  RobotId robot_id = 0;
  std::uint32_t incarnation = 0;
  double processed_until = 0.0;  // s, all data with stamps up to here has been applied
  std::uint32_t odom_processed = 0;
  std::uint32_t scans_processed = 0;
  std::uint32_t local_landmarks = 0;
  std::uint32_t global_landmarks = 0;
  std::uint32_t maps_received = 0;
  std::uint32_t maps_dropped = 0;
  std::uint64_t bytes_sent = 0;
  std::uint64_t bytes_received = 0;
  std::vector<RobotId> peers_aligned;
  std::vector<RobotId> peers_stale;  // liveliness lost; their last maps stay in the global map
  std::uint32_t tick_done = 0;       // lockstep: the last exchange tick carried out ...
  std::uint32_t tick_published = 0;  // ... and the maps and sightings published at it
  std::uint32_t tick_delivered = 0;  // ... the last tick whose messages from every peer have arrived
};

}  // namespace mapmesh
