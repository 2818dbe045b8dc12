#pragma once
// The thesis's fusion experiments (5.2-5.4), each written as a CSV into a directory;
// scripts/plots/fusion.py draws them:
// - fig61_62_bearing.csv: robot 2's bearing noise 0.5-4.5 deg, thesis circle pair (Figs. 61-62);
// - fig64_65_velocity.csv: robot 2's velocity noise 0.05-0.45 m/s, same layout (Figs. 64-65);
// - fig72_73_range.csv: robot 2's sensor range 9-12 m, low-overlap layout (Figs. 72-73);
// - table7_victoria.csv: Victoria Park robot pairs (Table 7), the real replay against its own reference;
// - fig66_69_low_overlap.csv: robot 2's bearing noise in Fig. 66's 5 %-overlap layout (Figs. 67-69);
// - fig75_76_vp_bearing.csv, fig77_78_vp_velocity.csv, fig80_81_vp_range.csv: the same sweeps on the
//   simulated Victoria Park (scenarios/victoria_sim.yaml: ground truth), trajectories 1 and 2;
// - table7_vp_sim.csv: Table 7 on the simulated Victoria Park: every pair of its four trajectories;
// - fig58_ellipses.csv: one circle-pair run's overlap landmarks, each robot's estimate and every
//   estimator's merged one with its covariance (Fig. 58).
// Alignment columns (similarity_true_ratio, ransac_true_recall) are the thesis's "map similarity"
// and "RANSAC success" (Figs. 67, 71, 75, 77, 80).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace mapmesh::lab {

struct ThesisFusionOptions {
  std::string scenarios_dir;  // where thesis_circle_pair.yaml etc. are
  std::string datasets_root;  // for Victoria Park
  int seeds = 0;              // Monte Carlo runs per point; 0: each experiment's own count (the thesis's:
                              // 50, 250 and 500 on Victoria Park, 500 at low overlap; 100 for the others)
  std::uint64_t first_seed = 1;
  int threads = 0;  // 0: the machine's cores
  bool oracle_alignment = false;
  std::vector<std::string> only;  // experiment names to run (kThesisFusionExperiments); empty: all
};

inline const std::vector<std::string> kThesisFusionExperiments{"bearing",     "velocity",   "range",       "victoria",
                                                               "low_overlap", "vp_bearing", "vp_velocity", "vp_range",
                                                               "vp_table7",   "fig58"};

void RunThesisFusion(const std::string& dir, const ThesisFusionOptions& options);

}  // namespace mapmesh::lab
