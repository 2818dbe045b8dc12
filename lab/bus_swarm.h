#pragma once
// A whole swarm in one process: a scenario's streams go to one AgentNode per robot, and the
// maps they publish are delivered to the others over an in-memory bus (each agent's radio gate
// still decides what it hears). Deterministic and fast: the agents' exchange logic (alignment,
// relay, liveliness, kills and restarts from checkpoints) without DDS.

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "agent/agent_node.h"
#include "common/config/scenario.h"
#include "common/metrics/landmark_metrics.h"

namespace mapmesh::lab {

struct BusSwarmOptions {
  std::string datasets_root;
  std::vector<std::pair<double, RobotId>> kills;     // (scenario time, robot)
  std::vector<std::pair<double, RobotId>> restarts;  // from the robot's last checkpoint
  // A lying peer: every sighting and answer this robot publishes reports its pose moved by
  // this much (m) in its map frame (a fault for tests: rendezvous verification must refuse it).
  std::map<RobotId, Eigen::Vector2d> sighting_offsets;
  std::set<RobotId> sightings_withheld;  // robots whose sightings and answers never reach the others
};

// One agent at the end of the run (its last incarnation).
struct BusAgentResult {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  bool alive_at_end = true;
  std::optional<Pose2> origin_truth;  // true pose of its map frame
  LandmarkMap local;
  GlobalMap global;
  std::vector<PoseStamp> trajectory;         // its last incarnation's estimated path (alive at the end) ...
  std::optional<double> frame_origin_stamp;  // ... in the frame fixed then
  std::vector<PeerReport> peers;
  AgentStats stats;
  MapQuality local_quality, global_quality;  // in its own frame (when the origin is known)
  MapQuality global_fitted;                  // after a rigid fit of the whole global map to the truth
  // Errors of its alignments against the truth, per aligned peer incarnation.
  // Against the true start poses of both frames (at the peer map's centroid), and against
  // the frames the two maps are really in (each map's rigid fit to the landmark truth): the
  // first includes both maps' own frame errors, the second is the alignment's own error.
  struct AlignmentError {
    PeerKey peer;
    double translation_m = 0.0, rotation_rad = 0.0;
    double fit_translation_m = -1.0, fit_rotation_rad = -1.0;  // -1: maps without signatures
  };
  std::vector<AlignmentError> alignment_errors;
  // Every transform this agent used for a peer frame during the run (sampled after each
  // exchange update), against the frames the two local maps were really in then (their rigid
  // fits to the landmark truth): the worst, per peer frame. A false alignment, however
  // short-lived, shows here. Empty without landmark truth.
  struct WorstAlignment {
    PeerKey peer;
    int transforms = 0;  // samples
    double translation_m = 0.0, rotation_rad = 0.0;
  };
  std::vector<WorstAlignment> worst_alignments;
};

struct BusSwarmResult {
  std::vector<BusAgentResult> agents;
  std::vector<Eigen::Vector2d> landmarks;  // truth
  std::vector<int> seen;                   // true landmarks some robot observed
  double wall_s = 0.0;
};

BusSwarmResult RunBusSwarm(const Scenario& scenario, const BusSwarmOptions& options);

}  // namespace mapmesh::lab
