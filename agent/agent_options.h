#pragma once
// Everything an agent is configured with: the scenario's `agent` section (docs/SCENARIOS.md).
// Each part is its module's own options struct, the one definition of its settings with their
// defaults and a Read beside them; this struct composes them and adds the agent's own. It is
// header-only, so the scenario can compose it without linking the agent.

#include "agent/exchange_options.h"
#include "agent/sensor_sync.h"
#include "common/config/scenario_limits.h"
#include "common/map/map_limits.h"
#include "common/slam/dead_reckoning_mapper.h"
#include "common/slam/local_slam.h"

namespace mapmesh {

struct AgentOptions {
  LocalSlamOptions slam;                // slam (the estimator), association, gates, ranges, region, FEJ
  DeadReckoningOptions dead_reckoning;  // slam: dead_reckoning
  SensorSync::Options sync;             // frame_at_first_landmark
  ExchangeOptions exchange;             // map_publish_period_s, fusion, alignment schedule, relay, silence
  MapLimits peer_limits;                // what a peer's map may be: landmarks, extent, uncertainty
  double status_period_s = 1.0;         // status_period_s: scenario seconds between status reports
  double checkpoint_period_s = 10.0;    // checkpoint_period_s: scenario seconds between checkpoints (0: none)
  double max_stamp_jump_s = 20.0;       // max_stamp_jump_s: sensor, link and map stamps this far ahead of ours
                                        // are implausible

  // Reads the whole agent section; the caller rejects keys nobody read (Finish).
  template <typename Reader>
  void Read(Reader& r) {
    slam.Read(r);
    dead_reckoning.Read(r);
    sync.Read(r);
    exchange.Read(r);
    peer_limits.Read(r);
    r.GetInRange("status_period_s", status_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetZeroOrInRange("checkpoint_period_s", checkpoint_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
    r.GetInRange("max_stamp_jump_s", max_stamp_jump_s, limits::kMinPeriodS, limits::kMaxPeriodS);
  }
};

}  // namespace mapmesh
