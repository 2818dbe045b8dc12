#pragma once
// The thesis's fusion experiments (5.2-5.4), each written as a CSV into a directory;
// scripts/plots/fusion.py draws them:
// - fig61_62_bearing.csv: robot 2's bearing noise 0.5-4.5 deg, thesis circle pair (Figs. 61-62);
// - fig64_65_velocity.csv: robot 2's velocity noise 0.05-0.45 m/s, same layout (Figs. 64-65);
// - fig72_73_range.csv: robot 2's sensor range 9-12 m, low-overlap layout (Figs. 72-73);
// - table7_victoria.csv: Victoria Park robot pairs (Table 7).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace mapmesh::lab {

struct ThesisFusionOptions {
  std::string scenarios_dir;  // where thesis_circle_pair.yaml etc. are
  std::string datasets_root;  // for Victoria Park
  int seeds = 100;            // Monte Carlo runs per point
  std::uint64_t first_seed = 1;
  int threads = 0;  // 0: the machine's cores
  bool oracle_alignment = false;
  std::vector<std::string> only;  // experiment names to run (bearing, velocity, range, victoria); empty: all
};

void RunThesisFusion(const std::string& dir, const ThesisFusionOptions& options);

}  // namespace mapmesh::lab
