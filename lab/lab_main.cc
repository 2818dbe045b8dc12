// mapmesh-lab: in-process experiments and Monte Carlo studies (no DDS). Each experiment
// writes a CSV; scripts/plots/ turns them into figures (docs/EXPERIMENTS.md).

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>

#include "common/app/process.h"
#include "lab/slam_experiment.h"
#include "sim_feeder/sources.h"

namespace mapmesh {
namespace {

int RunSlamCommand(const app::ProcessOptions& po, int seeds, std::uint64_t first_seed, bool hide,
                   const std::string& datasets, const std::string& csv_path, const std::string& trace_dir) {
  std::ofstream csv_file;
  if (!csv_path.empty()) {
    csv_file.open(csv_path);
    if (!csv_file) throw std::runtime_error(csv_path + ": cannot open for writing");
  }
  std::ostream& csv = csv_path.empty() ? std::cout : csv_file;
  csv << lab::SlamCsvHeader() << '\n';
  lab::SlamRunOptions options;
  options.datasets_root = ResolveDatasetsRoot(datasets, app::DefaultDatasetsRoot());
  options.hide_signatures = hide;
  std::map<std::string, double> sum;
  int rows = 0;
  for (int k = 0; k < seeds; ++k) {
    app::ProcessOptions run = po;
    if (seeds > 1 || first_seed > 0) run.sets.push_back("seed=" + std::to_string(first_seed + k));
    const std::optional<Scenario> sc = app::LoadScenarioOrReport("mapmesh-lab", run);
    if (!sc) return 2;
    for (const lab::SlamRunResult& r : lab::RunSlam(*sc, options)) {
      csv << lab::SlamCsvRow(r) << '\n';
      if (!trace_dir.empty()) {
        std::filesystem::create_directories(trace_dir);
        std::ofstream t(trace_dir + "/trace_seed" + std::to_string(r.seed) + "_robot" + std::to_string(r.robot) + ".csv");
        t << "t,position_error_m,heading_error_rad,pose_nees\n";
        for (const auto& p : r.trace) t << p.t << ',' << p.position_error_m << ',' << p.heading_error_rad << ',' << p.nees << '\n';
      }
      sum["rmse"] += r.landmark_rmse_m;
      sum["rmse_aligned"] += r.landmark_rmse_aligned_m;
      sum["nees"] += r.landmark_nees;
      sum["pose_nees"] += r.pose_nees;
      sum["traj"] += r.trajectory_rmse_m;
      sum["assoc"] += r.associations;
      sum["wrong"] += r.wrong_associations;
      ++rows;
    }
    if (isatty(STDERR_FILENO)) std::fprintf(stderr, "\rmapmesh-lab: run %d/%d", k + 1, seeds);
  }
  if (isatty(STDERR_FILENO)) std::fprintf(stderr, "\n");
  if (rows > 0) {
    std::fprintf(stderr,
                 "mean over %d robot runs: landmark RMSE %.3f m (aligned %.3f m), landmark NEES %.2f, pose NEES %.2f, "
                 "trajectory RMSE %.3f m",
                 rows, sum["rmse"] / rows, sum["rmse_aligned"] / rows, sum["nees"] / rows, sum["pose_nees"] / rows, sum["traj"] / rows);
    if (hide) {
      std::fprintf(stderr, ", wrong associations %.0f of %.0f (%.3f %%)", sum["wrong"], sum["assoc"],
                   sum["assoc"] > 0 ? 100.0 * sum["wrong"] / sum["assoc"] : 0.0);
    }
    std::fprintf(stderr, "\n");
  }
  return 0;
}

int Run(int argc, char** argv) {
  CLI::App cli{"mapmesh-lab: in-process experiments and Monte Carlo studies (CSV out)"};
  cli.require_subcommand(1);
  app::ProcessOptions po;
  int seeds = 1;
  std::uint64_t first_seed = 0;
  bool hide = false;
  std::string datasets, csv, trace;
  CLI::App* slam = cli.add_subcommand("slam", "run every robot's local SLAM on a scenario, score it against the truth");
  app::AddScenarioOptions(*slam, po);
  slam->add_option("--seeds", seeds, "Monte Carlo runs (seeds first-seed, first-seed + 1, ...)")->check(CLI::PositiveNumber);
  slam->add_option("--first-seed", first_seed, "first seed (default: the scenario's, for one run; 0 otherwise)");
  slam->add_flag("--hide-signatures", hide, "give the estimator unidentified observations and score its associations");
  slam->add_option("--datasets", datasets, "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  slam->add_option("--csv", csv, "write the CSV here (default: stdout)");
  slam->add_option("--trace", trace, "also write each robot's per-scan pose errors to CSVs in this directory");
  if (auto code = app::ParseArgs(cli, "mapmesh-lab", argc, argv)) return *code;
  if (slam->parsed()) return RunSlamCommand(po, seeds, first_seed, hide, datasets, csv, trace);
  return 2;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-lab", [&] { return mapmesh::Run(argc, argv); });
}
