#include "lab/thesis_fusion.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "common/config/scenario.h"
#include "lab/fusion_experiment.h"

namespace mapmesh::lab {
namespace {

void Write(const std::string& path, const std::string& text) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  f << text;
}

bool Wanted(const ThesisFusionOptions& o, const std::string& name) {
  return o.only.empty() || std::find(o.only.begin(), o.only.end(), name) != o.only.end();
}

std::string FormatValue(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// One updating line on a terminal, one line per experiment otherwise.
std::function<void(int, int)> Progress(const std::string& what) {
  return [what](int done, int total) {
    if (isatty(STDERR_FILENO)) {
      std::fprintf(stderr, "\rmapmesh-lab: %s %d/%d   ", what.c_str(), done, total);
      if (done == total) std::fprintf(stderr, "\n");
    } else if (done == total) {
      std::fprintf(stderr, "mapmesh-lab: %s done (%d runs)\n", what.c_str(), total);
    }
  };
}

// Sweeps `key` over values on a scenario file (its first `agents` robots; 0: all) and writes
// the CSV; `seeds` runs per value unless the options give a count. With pairs, every run scores
// each pair.
void Sweep(const std::string& dir, const std::string& name, const std::string& scenario, const std::string& key,
           const std::string& parameter, const std::vector<double>& values, int seeds, const ThesisFusionOptions& o,
           int agents = 0, const std::vector<std::pair<RobotId, RobotId>>& pairs = {}) {
  FusionSweepOptions so;
  so.values = values;
  so.seeds = o.seeds > 0 ? o.seeds : seeds;
  so.pairs = pairs;
  so.first_seed = o.first_seed;
  so.threads = o.threads;
  so.trial.oracle_alignment = o.oracle_alignment;
  so.progress = Progress(name);
  const std::string file = o.scenarios_dir + "/" + scenario;
  const auto make = [&](double value, std::uint64_t seed) {
    std::vector<ConfigOverride> sets{ParseOverride("seed=" + std::to_string(seed))};
    if (!key.empty()) sets.push_back(ParseOverride(key + "=" + FormatValue(value)));
    return LoadScenario(file, sets, agents);
  };
  Write(dir + "/" + name + ".csv",
        FusionSweepCsv(parameter, SummariseFusionSweep(RunFusionSweep(make, so), so.trial.methods)));
}

}  // namespace

void RunThesisFusion(const std::string& dir, const ThesisFusionOptions& o) {
  std::filesystem::create_directories(dir);
  const std::vector<double> bearings{0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5};
  const std::vector<double> velocities{0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45};
  const std::string bearing_key = "robots.list[1].sensor.sigma_bearing_deg";
  const std::string velocity_key = "robots.list[1].motion.sigma_v_mps";
  const std::string range_key = "robots.list[1].sensor.max_range_m";
  if (Wanted(o, "bearing")) {
    Sweep(dir, "fig61_62_bearing", "thesis_circle_pair.yaml", bearing_key, "bearing_sigma_deg", bearings, 100, o);
  }
  if (Wanted(o, "velocity")) {
    Sweep(dir, "fig64_65_velocity", "thesis_circle_pair.yaml", velocity_key, "velocity_sigma_mps", velocities, 100, o);
  }
  if (Wanted(o, "range")) {
    Sweep(dir, "fig72_73_range", "thesis_low_overlap_range.yaml", range_key, "range_m", {9.0, 10.0, 11.0, 12.0}, 100,
          o);
  }
  // Fig. 66's layout (5 % overlap), robot 2's bearing noise: Figs. 67-69, 500 runs a point.
  if (Wanted(o, "low_overlap")) {
    Sweep(dir, "fig66_69_low_overlap", "thesis_low_overlap.yaml", bearing_key, "bearing_sigma_deg", bearings, 500, o);
  }
  // The simulated Victoria Park (victoria_sim.yaml, lab/victoria_world.h), with ground truth:
  // trajectories 1 and 2 for the sweeps (Figs. 75-81, the thesis's 50, 250 and 500 runs a
  // point), every pair of the four for Table 7 (50 runs, the thesis's pairs in its order).
  if (Wanted(o, "vp_bearing")) {
    Sweep(dir, "fig75_76_vp_bearing", "victoria_sim.yaml", bearing_key, "bearing_sigma_deg", bearings, 50, o, 2);
  }
  if (Wanted(o, "vp_velocity")) {
    Sweep(dir, "fig77_78_vp_velocity", "victoria_sim.yaml", velocity_key, "velocity_sigma_mps", velocities, 250, o, 2);
  }
  if (Wanted(o, "vp_range")) {
    Sweep(dir, "fig80_81_vp_range", "victoria_sim.yaml", range_key, "range_m",
          {9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0, 16.0, 17.0}, 500, o, 2);
  }
  if (Wanted(o, "vp_table7")) {
    Sweep(dir, "table7_vp_sim", "victoria_sim.yaml", "", "none", {0.0}, 50, o, 4,
          {{2, 1}, {2, 3}, {2, 4}, {3, 1}, {3, 4}, {4, 1}});
  }
  // Fig. 58: every estimate of the overlap landmarks in one run of the circle pair (the first
  // seed), with its covariance, for the ellipse plot.
  if (Wanted(o, "fig58")) {
    const Scenario s = LoadScenario(o.scenarios_dir + "/thesis_circle_pair.yaml",
                                    {ParseOverride("seed=" + std::to_string(o.first_seed))});
    FusionTrialOptions trial;
    trial.oracle_alignment = o.oracle_alignment;
    trial.keep_estimates = true;
    std::mt19937_64 rng(o.first_seed * 7919 + 17);  // as the sweeps' runs
    const FusionTrialResult r = RunFusionTrial(RunSlam(s, SlamRunOptions{}), trial, rng);
    Write(dir + "/fig58_ellipses.csv", OverlapEstimatesCsv(r.estimates));
    Progress("fig58")(1, 1);
  }
  if (Wanted(o, "victoria")) {
    const std::string file = o.scenarios_dir + "/victoria_4.yaml";
    SlamRunOptions so;
    so.datasets_root = o.datasets_root;
    const Scenario whole = LoadScenario(file, {}, 1);
    const Scenario split = LoadScenario(file);
    const auto reference = RunSlam(whole, so);
    Progress("victoria reference run")(1, 1);
    const auto robots = RunSlam(split, so);
    std::mt19937_64 rng(split.seed);
    Write(dir + "/table7_victoria.csv", VictoriaPairsCsv(RunVictoriaPairs(robots, reference.at(0).map, {}, rng)));
    Progress("victoria pairs")(1, 1);
  }
}

}  // namespace mapmesh::lab
