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

// Sweeps `key` over values on a scenario file and writes the CSV.
void Sweep(const std::string& dir, const std::string& name, const std::string& scenario, const std::string& key,
           const std::string& parameter, const std::vector<double>& values, const ThesisFusionOptions& o) {
  FusionSweepOptions so;
  so.values = values;
  so.seeds = o.seeds;
  so.first_seed = o.first_seed;
  so.threads = o.threads;
  so.trial.oracle_alignment = o.oracle_alignment;
  so.progress = Progress(name);
  const std::string file = o.scenarios_dir + "/" + scenario;
  const auto make = [&](double value, std::uint64_t seed) {
    return LoadScenario(file,
                        {ParseOverride(key + "=" + FormatValue(value)), ParseOverride("seed=" + std::to_string(seed))});
  };
  Write(dir + "/" + name + ".csv",
        FusionSweepCsv(parameter, SummariseFusionSweep(RunFusionSweep(make, so), so.trial.methods)));
}

}  // namespace

void RunThesisFusion(const std::string& dir, const ThesisFusionOptions& o) {
  std::filesystem::create_directories(dir);
  if (Wanted(o, "bearing")) {
    Sweep(dir, "fig61_62_bearing", "thesis_circle_pair.yaml", "robots.list[1].sensor.sigma_bearing_deg",
          "bearing_sigma_deg", {0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5}, o);
  }
  if (Wanted(o, "velocity")) {
    Sweep(dir, "fig64_65_velocity", "thesis_circle_pair.yaml", "robots.list[1].motion.sigma_v_mps",
          "velocity_sigma_mps", {0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45}, o);
  }
  if (Wanted(o, "range")) {
    Sweep(dir, "fig72_73_range", "thesis_low_overlap_range.yaml", "robots.list[1].sensor.max_range_m", "range_m",
          {9.0, 10.0, 11.0, 12.0}, o);
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
