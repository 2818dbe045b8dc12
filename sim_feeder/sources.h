#pragma once
// Builds the feed a scenario asks for: the simulator, or a dataset replay.

#include <memory>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "sim_feeder/feed_source.h"
#include "sim_feeder/replay_source.h"

namespace mapmesh {

// The datasets root: dir if given, else $MAPMESH_DATASETS, else fallback.
std::string ResolveDatasetsRoot(const std::string& dir, const std::string& fallback);

struct Feed {
  std::unique_ptr<FeedSource> source;
  std::vector<ReplayCounts> counts;  // datasets: what was read per robot
};

// Builds the source; for datasets it reads the files (under datasets_root) and sets
// scenario.duration_s to the replayed length. Throws ConfigError for a bad world and
// DatasetError for a missing or malformed dataset.
Feed MakeFeed(Scenario& scenario, const std::string& datasets_root);

}  // namespace mapmesh
