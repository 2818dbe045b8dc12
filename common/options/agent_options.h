#pragma once
// Everything an agent is configured with: the scenario's `agent` section (docs/SCENARIOS.md).
// Each part is its module's own options struct, the one definition of its settings with their
// defaults and a Read beside them; this struct composes them and adds the agent's own. Like
// every header of common/options/ it is header-only and includes nothing of agent/: the
// scenario loader (common/config/, the floor above) composes it without the agent's code.

#include <algorithm>
#include <cstddef>

#include "common/map/map_limits.h"
#include "common/options/exchange_options.h"
#include "common/options/rendezvous_options.h"
#include "common/options/sensor_sync_options.h"
#include "common/slam/dead_reckoning_mapper.h"
#include "common/slam/local_slam.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

struct AgentOptions {
  LocalSlamOptions slam;                // slam (the estimator), association, gates, ranges, region, FEJ
  DeadReckoningOptions dead_reckoning;  // slam: dead_reckoning
  SensorSyncOptions sync;               // frame_at_first_landmark
  ExchangeOptions exchange;             // map_publish_period_s, fusion, alignment schedule, relay, silence
  RendezvousOptions rendezvous;         // rendezvous_period_s
  MapLimits peer_limits;                // what a peer's map may be: landmarks, extent, uncertainty
  double status_period_s = 1.0;         // status_period_s: scenario seconds between status reports
  double checkpoint_period_s = 10.0;    // checkpoint_period_s: scenario seconds between checkpoints (0: none)
  double max_stamp_jump_s = 20.0;       // max_stamp_jump_s: sensor, link and map stamps this far ahead of ours
                                        // are implausible
  double liveliness_lease_s = 0.0;  // liveliness_lease_s: DDS liveliness lease of the agents' writers (0: automatic,
                                    // LivelinessLeaseS)

  // The lease in use: as given, else 1 s up to 16 robots and robots / 16 s beyond. Each agent's
  // writers announce their liveliness to every process once a lease; a longer lease in a larger
  // swarm keeps those announcements at 16 per second per process (at 64 agents with 1 s they
  // cost 15 % of the agents' CPU), and a dead agent is noticed after about that long.
  double LivelinessLeaseS(std::size_t robots) const {
    return liveliness_lease_s > 0.0 ? liveliness_lease_s : std::max(1.0, static_cast<double>(robots) / 16.0);
  }

  // Reads the whole agent section; the caller rejects keys nobody read (Finish).
  template <typename Reader>
  void Read(Reader& r) {
    slam.Read(r);
    dead_reckoning.Read(r);
    sync.Read(r);
    exchange.Read(r);
    exchange.chain_join = slam.submaps.join;
    rendezvous.Read(r);
    peer_limits.Read(r);
    r.GetInRange("status_period_s", status_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetZeroOrInRange("checkpoint_period_s", checkpoint_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetInRange("max_stamp_jump_s", max_stamp_jump_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetZeroOrInRange("liveliness_lease_s", liveliness_lease_s, limits::kMinLeaseS, limits::kMaxPeriodS);
  }
};

}  // namespace mapmesh
