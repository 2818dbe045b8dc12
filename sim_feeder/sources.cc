#include "sim_feeder/sources.h"

#include <cstdlib>

#include "sim_feeder/mrclam.h"
#include "sim_feeder/simulator.h"
#include "sim_feeder/victoria_park.h"
#include "sim_feeder/world.h"

namespace mapmesh {

std::string ResolveDatasetsRoot(const std::string& dir, const std::string& fallback) {
  if (!dir.empty()) return dir;
  const char* env = std::getenv("MAPMESH_DATASETS");
  return env && *env ? std::string(env) : fallback;
}

Feed MakeFeed(Scenario& scenario, const std::string& datasets_root) {
  Feed feed;
  if (!scenario.source.IsDataset()) {
    feed.source = std::make_unique<Simulator>(scenario, BuildWorld(scenario));
    return feed;
  }
  // An absolute dataset path is taken as it is (a variant made by scripts/mrclam-variant, say).
  const std::string& name = scenario.source.dataset;
  const std::string dir = !name.empty() && name.front() == '/' ? name : datasets_root + "/" + name;
  ReplayData data = scenario.source.type == SourceType::kMrclam ? LoadMrclam(dir, scenario)
                                                                : LoadVictoriaPark(dir, scenario);
  if (scenario.duration_given) Truncate(data, scenario.duration_s);
  scenario.duration_s = data.duration_s;
  feed.counts = data.counts;
  feed.source = std::make_unique<ReplaySource>(std::move(data), scenario.radio, scenario.seed);
  return feed;
}

}  // namespace mapmesh
