#pragma once
// RendezvousOptions: what an agent does with the robots it sees (agent/rendezvous_tracker.h):
// the scenario's agent.rendezvous_period_s, and the tracker's bounds.

#include "common/merge/rendezvous.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

struct RendezvousOptions {
  double period_s = 1.0;          // agent.rendezvous_period_s: at most one sighting of each peer published this often
  double window_s = 60.0;         // own poses and sightings are kept this long (later answers find nothing)
  double mutual_within_s = 0.25;  // two robots' sightings of each other this close in time: a mutual rendezvous
  double max_pose_gap_s = 1.0;    // the own pose at a stamp is interpolated between poses at most this far apart
  int max_pairs = 30;             // per peer frame, the newest correspondences kept ...
  int max_mutual = 10;            // ... and mutual rendezvous
  int max_pending = 256;          // peers' sightings waiting for us to reach their stamp (the oldest go first)
  int max_frames_per_robot = 8;   // peer frames tracked per robot (the least recently updated go first)
  RendezvousFitOptions fit;

  template <typename Reader>
  void Read(Reader& r) {
    r.GetInRange("rendezvous_period_s", period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
  }
};

}  // namespace mapmesh
