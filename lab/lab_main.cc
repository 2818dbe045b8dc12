// mapmesh-lab: in-process experiments and Monte Carlo studies (no DDS). Each experiment
// writes a CSV; scripts/plots/ turns them into figures (docs/EXPERIMENTS.md).

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>

#include "common/app/process.h"
#include "common/io/run_files.h"
#include "lab/alignment_experiment.h"
#include "lab/bus_swarm.h"
#include "lab/fusion_experiment.h"
#include "lab/pairs_experiment.h"
#include "lab/reference.h"
#include "lab/search_experiment.h"
#include "lab/slam_experiment.h"
#include "lab/thesis_alignment.h"
#include "lab/thesis_fusion.h"
#include "lab/victoria_world.h"
#include "sim_feeder/sources.h"

namespace mapmesh {
namespace {

// The CSV output: the file given, or stdout when none is.
class CsvOut {
 public:
  explicit CsvOut(const std::string& path) {
    if (path.empty()) return;
    file_.open(path);
    if (!file_) throw std::runtime_error(path + ": cannot open for writing");
  }
  std::ostream& stream() { return file_.is_open() ? file_ : std::cout; }

 private:
  std::ofstream file_;
};

// The simulated Victoria Park: the whole run as one robot, then its map and path cut into a scenario.
int RunVictoriaWorldCommand(const std::string& out, const std::string& datasets, const lab::VictoriaWorldOptions& o) {
  if (o.robots > o.segments) {
    std::fprintf(stderr, "mapmesh-lab: --robots %d is more than --segments %d\n", o.robots, o.segments);
    return 2;
  }
  lab::SlamRunOptions so;
  so.datasets_root = ResolveDatasetsRoot(datasets, app::DefaultDatasetsRoot());
  const Scenario whole = LoadScenario(MAPMESH_SOURCE_DIR "/scenarios/victoria_4.yaml", {}, 1);
  std::fprintf(stderr, "mapmesh-lab: the whole Victoria Park run as one robot (about 15 s)\n");
  const std::vector<lab::SlamRunResult> run = lab::RunSlam(whole, so);
  const lab::VictoriaWorld world = lab::DeriveVictoriaWorld(run.at(0), o);
  std::filesystem::create_directories(out + "/data");
  const std::string csv = "data/victoria_sim_landmarks.csv";
  for (const auto& [path, text] : {std::pair{out + "/" + csv, lab::VictoriaLandmarksCsv(world)},
                                   std::pair{out + "/victoria_sim.yaml", lab::VictoriaScenarioYaml(world, csv)}}) {
    std::ofstream f(path);
    if (!f || !(f << text)) throw std::runtime_error(path + ": cannot write");
  }
  std::fprintf(stderr, "mapmesh-lab: %zu landmarks; spans", world.landmarks.size());
  for (std::size_t r = 0; r < world.kept.size(); ++r)
    std::fprintf(stderr, " %d (%.0f m, %d landmarks)", world.kept[r] + 1, world.length_m[r], world.neighbourhood[r]);
  std::fprintf(stderr, "; landmarks shared:");
  for (std::size_t i = 0; i < world.kept.size(); ++i)
    for (std::size_t j = i + 1; j < world.kept.size(); ++j)
      std::fprintf(stderr, " %zu&%zu %d", i + 1, j + 1, world.shared[i][j]);
  std::fprintf(stderr, "; written to %s/victoria_sim.yaml\n", out.c_str());
  return 0;
}

int RunSlamCommand(const app::ProcessOptions& po, int seeds, std::uint64_t first_seed, bool hide,
                   const std::string& datasets, const std::string& csv_path, const std::string& trace_dir) {
  CsvOut out(csv_path);
  std::ostream& csv = out.stream();
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
        std::ofstream t(trace_dir + "/trace_seed" + std::to_string(r.seed) + "_robot" + std::to_string(r.robot) +
                        ".csv");
        t << "t,position_error_m,heading_error_rad,pose_nees\n";
        for (const auto& p : r.trace)
          t << p.t << ',' << p.position_error_m << ',' << p.heading_error_rad << ',' << p.nees << '\n';
      }
      sum["rmse"] += r.landmark_rmse_m;
      sum["rmse_aligned"] += r.landmark_rmse_aligned_m;
      sum["nees"] += r.landmark_nees;
      sum["pose_nees"] += r.pose_nees;
      sum["traj"] += r.trajectory_rmse_m;
      sum["traj_aligned"] += r.trajectory_rmse_aligned_m;
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
                 "trajectory RMSE %.3f m (aligned %.3f m)",
                 rows, sum["rmse"] / rows, sum["rmse_aligned"] / rows, sum["nees"] / rows, sum["pose_nees"] / rows,
                 sum["traj"] / rows, sum["traj_aligned"] / rows);
    if (hide) {
      std::fprintf(stderr, ", wrong associations %.0f of %.0f (%.3f %%)", sum["wrong"], sum["assoc"],
                   sum["assoc"] > 0 ? 100.0 * sum["wrong"] / sum["assoc"] : 0.0);
    }
    std::fprintf(stderr, "\n");
  }
  return 0;
}

int RunPairsCommand(const app::ProcessOptions& po, const std::string& datasets, const std::string& csv_path,
                    const std::vector<std::string>& searches) {
  const std::optional<Scenario> sc = app::LoadScenarioOrReport("mapmesh-lab", po);
  if (!sc) return 2;
  lab::SlamRunOptions options;
  options.datasets_root = ResolveDatasetsRoot(datasets, app::DefaultDatasetsRoot());
  const auto robots = lab::RunSlam(*sc, options);
  CsvOut out(csv_path);
  std::ostream& csv = out.stream();
  csv << lab::PairsCsvHeader() << '\n';
  // The same robots' maps for every search, each from the scenario's seed.
  for (const std::string& name : searches) {
    AlignmentOptions align;
    align.search = *ParseChoice(kTransformSearch, name);
    std::mt19937_64 rng(sc->seed);
    for (const auto& p : lab::AlignPairs(robots, *sc, align, rng)) csv << lab::PairsCsvRow(p) << '\n';
  }
  return 0;
}

int RunSearchCommand(const lab::SearchComparisonOptions& options, const AlignmentOptions& align,
                     const std::string& csv_path) {
  const auto trials = lab::RunSearchComparison(options, align);
  CsvOut out(csv_path);
  std::ostream& csv = out.stream();
  csv << lab::SearchCsvHeader() << '\n';
  for (const auto& t : trials) csv << lab::SearchCsvRow(t) << '\n';
  std::fprintf(stderr, "%s", lab::SearchSummary(trials).c_str());
  return 0;
}

int RunAlignCommand(const lab::MapPairOptions& maps, const AlignmentOptions& align, int trials, std::uint64_t seed,
                    const std::string& csv_path) {
  CsvOut out(csv_path);
  std::ostream& csv = out.stream();
  csv << lab::AlignCsvHeader() << '\n';
  const auto results = lab::RunAlignTrials(maps, align, trials, seed);
  int accepted = 0, correct = 0;
  std::vector<double> ms;
  double precision = 0.0;
  for (const auto& t : results) {
    csv << lab::AlignCsvRow(t) << '\n';
    accepted += t.verdict == AlignmentVerdict::kAccepted;
    correct += t.correct;
    ms.push_back(t.match_ms + t.ransac_ms);
    precision += t.candidate_precision;
  }
  std::sort(ms.begin(), ms.end());
  std::fprintf(stderr,
               "%d trials: accepted %d, correct (<= 0.2 m, 1 deg) %d (%.1f %%), candidate precision %.3f, "
               "median time %.2f ms\n",
               trials, accepted, correct, 100.0 * correct / std::max(1, trials), precision / std::max(1, trials),
               ms.empty() ? 0.0 : ms[ms.size() / 2]);
  return 0;
}

int RunFusionCommand(const app::ProcessOptions& po, const std::string& param, const std::vector<double>& values,
                     lab::FusionSweepOptions so, const std::string& datasets, const std::string& csv_path) {
  so.values = values;
  so.slam.datasets_root = ResolveDatasetsRoot(datasets, app::DefaultDatasetsRoot());
  so.progress = [](int done, int total) {
    if (isatty(STDERR_FILENO))
      std::fprintf(stderr, "\rmapmesh-lab: run %d/%d%s", done, total, done == total ? "\n" : "");
  };
  // Validate the scenario and the key once, with a one-line error, before the sweep.
  app::ProcessOptions first = po;
  first.sets.push_back(param + "=" + std::to_string(values.front()));
  if (!app::LoadScenarioOrReport("mapmesh-lab", first)) return 2;
  const auto make = [&](double value, std::uint64_t seed) {
    std::vector<ConfigOverride> overrides;
    for (const auto& s : po.sets) overrides.push_back(ParseOverride(s));
    overrides.push_back(ParseOverride(param + "=" + std::to_string(value)));
    overrides.push_back(ParseOverride("seed=" + std::to_string(seed)));
    return LoadScenario(po.scenario_path, overrides, po.agents);
  };
  CsvOut out(csv_path);
  out.stream() << lab::FusionSweepCsv(param,
                                      lab::SummariseFusionSweep(lab::RunFusionSweep(make, so), so.trial.methods));
  return 0;
}

std::vector<std::pair<double, RobotId>> ParseEvents(const std::vector<std::string>& items, const char* what) {
  std::vector<std::pair<double, RobotId>> out;
  for (const std::string& item : items) {
    const auto at = item.find('@');
    try {
      if (at == std::string::npos) throw std::invalid_argument(item);
      out.emplace_back(std::stod(item.substr(at + 1)), static_cast<RobotId>(std::stoul(item.substr(0, at))));
    } catch (const std::exception&) {
      throw std::runtime_error(std::string("--") + what + " " + item + ": expected ID@T (robot id @ scenario seconds)");
    }
  }
  return out;
}

int RunBusCommand(const app::ProcessOptions& po, const std::vector<std::string>& kills,
                  const std::vector<std::string>& restarts, const std::string& datasets, const std::string& out_dir) {
  const std::optional<Scenario> sc = app::LoadScenarioOrReport("mapmesh-lab", po);
  if (!sc) return 2;
  lab::BusSwarmOptions o;
  o.datasets_root = ResolveDatasetsRoot(datasets, app::DefaultDatasetsRoot());
  o.kills = ParseEvents(kills, "kill");
  o.restarts = ParseEvents(restarts, "restart");
  const lab::BusSwarmResult r = lab::RunBusSwarm(*sc, o);
  // The agents' final maps as a swarm run writes them (agent_<id>/local_map.json and
  // global_map.json), for comparison with one: a live agent's maps, a dead one's last checkpoint.
  if (!out_dir.empty()) {
    for (const auto& a : r.agents) {
      const std::string dir = out_dir + "/agent_" + std::to_string(a.robot);
      std::filesystem::create_directories(dir);
      io::WriteJsonAtomic(dir + "/local_map.json", io::MapToJson(a.local));
      io::WriteJsonAtomic(dir + "/global_map.json",
                          a.alive_at_end ? io::GlobalMapToJson(a.global) : io::MapToJson(a.global.map));
      io::WriteJsonAtomic(dir + "/trajectory.json", io::TrajectoryToJson(a.trajectory, a.frame_origin_stamp));
    }
  }
  std::printf("%s: %zu agents, %.1f s wall (in-memory bus)\n", sc->name.c_str(), r.agents.size(), r.wall_s);
  // Without landmark truth (Victoria Park) the error columns are "-" and peers are listed bare.
  const bool truth = !r.landmarks.empty();
  std::printf("%3s %5s %4s %8s %8s %8s %8s %8s %8s %8s  %s\n", "id", "alive", "inc", "lm_loc", "rmse_loc", "lm_glob",
              "rmse_glb", "nees_glb", "cons_glb", "cov_glb", truth ? "aligned peers (error m/deg)" : "aligned peers");
  auto metric = [&](double v, const char* format) {
    char buf[32];
    std::snprintf(buf, sizeof buf, format, v);
    return truth ? std::string(buf) : std::string("-");
  };
  for (const auto& a : r.agents) {
    std::string peers;
    if (truth) {
      for (const auto& e : a.alignment_errors) {
        char buf[96];
        std::snprintf(buf, sizeof buf, " %u.%u(%.2f/%.2f fit %.2f/%.2f)", e.peer.robot, e.peer.incarnation,
                      e.translation_m, RadToDeg(e.rotation_rad), e.fit_translation_m, RadToDeg(e.fit_rotation_rad));
        peers += buf;
      }
    } else {
      for (const PeerReport& p : a.peers) {
        if (p.aligned) peers += " " + std::to_string(p.key.robot) + "." + std::to_string(p.key.incarnation);
      }
    }
    std::printf("%3u %5s %4u %8zu %8s %8zu %8s %8s %8s %8s %s\n", a.robot, a.alive_at_end ? "yes" : "no", a.incarnation,
                a.local.size(), metric(a.local_quality.rmse_m, "%.3f").c_str(), a.global.map.size(),
                metric(a.global_quality.rmse_m, "%.3f").c_str(), metric(a.global_quality.nees_mean, "%.2f").c_str(),
                metric(a.global_quality.consistent_ratio, "%.2f").c_str(),
                metric(a.global_quality.coverage, "%.2f").c_str(), peers.c_str());
  }
  // When each peer frame was first aligned, and by what.
  std::printf(
      "\nfirst alignments (peer.incarnation@scenario s by source; rendezvous fits: refused/unjudged/confirmed):\n");
  for (const auto& a : r.agents) {
    std::string line;
    for (const PeerReport& p : a.peers) {
      if (p.own_checkpoint) continue;
      char buf[128];
      if (p.ever_aligned) {
        std::snprintf(buf, sizeof buf, " %u.%u@%.1f %s", p.key.robot, p.key.incarnation, p.aligned_since,
                      ToString(p.first_aligned_by));
      } else {
        std::snprintf(buf, sizeof buf, " %u.%u never", p.key.robot, p.key.incarnation);
      }
      line += buf;
      if (p.rendezvous_fits > 0) {
        std::snprintf(buf, sizeof buf, "(%d/%d/%d)", p.rendezvous_refused, p.rendezvous_unjudged,
                      p.rendezvous_confirmed);
        line += buf;
      }
    }
    std::printf("%3u%s\n", a.robot, line.c_str());
  }
  if (truth) {
    std::printf("\nglobal maps after a rigid fit to the truth (rmse m, nees, landmarks matched):\n");
    double sum = 0.0;
    for (const auto& a : r.agents) {
      std::printf("%3u %.3f %.2f %d\n", a.robot, a.global_fitted.rmse_m, a.global_fitted.nees_mean,
                  a.global_fitted.matched);
      sum += a.global_fitted.rmse_m;
    }
    std::printf("mean %.3f\n\n", r.agents.empty() ? 0.0 : sum / static_cast<double>(r.agents.size()));
    std::printf(
        "worst transform used per peer frame, against the maps' fits to the truth at the time (m/deg, samples):\n");
    for (const auto& a : r.agents) {
      std::string line;
      for (const auto& w : a.worst_alignments) {
        char buf[96];
        std::snprintf(buf, sizeof buf, " %u.%u(%.2f/%.2f, %d)", w.peer.robot, w.peer.incarnation, w.translation_m,
                      RadToDeg(w.rotation_rad), w.transforms);
        line += buf;
      }
      std::printf("%3u%s\n", a.robot, line.c_str());
    }
  }
  return 0;
}

// One reference map's figures (and, with with_map, the map itself), as reference.json holds
// them (docs/EXPERIMENTS.md "The limit").
io::json ReferenceMapJson(const lab::ReferenceMap& m, bool with_map) {
  const BatchSolution& s = m.solution;
  io::json j = {{"landmarks", m.landmarks},
                {"matched", m.matched},
                {"rmse_aligned_m", m.evaluated ? io::json(m.rmse_aligned_m) : io::json()},
                {"rmse_m", m.rmse_m ? io::json(*m.rmse_m) : io::json()},
                {"nees_mean", m.evaluated && s.covariance_ok ? io::json(m.nees_mean) : io::json()},
                {"consistent_ratio", m.evaluated && s.covariance_ok ? io::json(m.consistent_ratio) : io::json()},
                {"frame", m.rmse_m ? "world" : "aligned"},
                {"solve_s", m.solve_s},
                {"solves", s.solves},
                {"iterations", s.report.iterations},
                {"converged", s.report.converged},
                {"stop", s.report.stop},
                {"chi2_per_dof", s.chi2_per_dof},
                {"variables", s.variables},
                {"observations", s.observations},
                {"covariance_ok", s.covariance_ok}};
  if (!s.components.empty()) {
    // A centralized solve: the sightings it used, and the robots whose data the rest share too
    // little with to tie their frames (components of their own, each in its own gauge).
    j["sightings"] = s.sightings;
    j["cost"] = s.report.final_cost;
    io::json comps = io::json::array();
    io::json unconnected = io::json::array();
    for (std::size_t k = 0; k < s.components.size(); ++k) {
      const BatchComponent& c = s.components[k];
      comps.push_back({{"robots", c.robots}, {"landmarks", c.landmarks}, {"in_world", c.in_world}});
      if (k > 0) {
        for (RobotId id : c.robots) unconnected.push_back(id);
      }
    }
    j["components"] = comps;
    j["unconnected"] = unconnected;
    j["observations_left_out"] = s.observations_left_out;
    j["sightings_left_out"] = s.sightings_left_out;
    if (m.from_truth) {
      j["from_truth"] = {{"cost", m.from_truth->final_cost},
                         {"iterations", m.from_truth->iterations},
                         {"converged", m.from_truth->converged}};
    }
  }
  if (with_map) {
    j["map"] = io::MapToJson(s.map);
    // Each landmark's component (by signature), where there are several.
    if (s.components.size() > 1) {
      io::json of = io::json::object();
      for (const auto& [sig, c] : s.landmark_component) of[std::to_string(sig)] = c;
      j["landmark_component"] = of;
    }
  }
  return j;
}

io::json ReferenceJson(const lab::Reference& r) {
  io::json j = {{"available", r.available},
                {"why_none", r.available ? io::json() : io::json(r.why_none)},
                {"total_s", r.total_s}};
  if (!r.available) return j;
  j["loss"] = r.loss;
  if (!r.until.empty()) {
    io::json until = io::json::object();
    for (const auto& [id, t] : r.until) until[std::to_string(id)] = t;
    j["until"] = until;
  }
  j["central"] = ReferenceMapJson(r.central, true);
  j["central_known_starts"] = r.has_known_starts ? ReferenceMapJson(r.central_known_starts, true) : io::json();
  io::json own = io::json::object();
  for (const auto& [id, m] : r.own) own[std::to_string(id)] = ReferenceMapJson(m, true);
  j["own_batch"] = own;
  j["known_pose"] = r.known_pose ? ReferenceMapJson(*r.known_pose, true) : io::json();
  io::json own_known = io::json::object();
  for (const auto& [id, m] : r.own_known_pose) own_known[std::to_string(id)] = ReferenceMapJson(m, false);
  j["own_known_pose"] = own_known;
  if (!r.known_pose) j["known_pose_why_none"] = r.known_pose_why_none;
  return j;
}

// "ROBOT=T" of --until: a robot id and a time, not negative.
std::optional<std::pair<RobotId, double>> ParseUntil(const std::string& v) {
  const auto eq = v.find('=');
  if (eq == std::string::npos || eq == 0 || !std::isdigit(static_cast<unsigned char>(v[0]))) return std::nullopt;
  try {
    std::size_t n = 0, m = 0;
    const unsigned long robot = std::stoul(v.substr(0, eq), &n);
    const double t = std::stod(v.substr(eq + 1), &m);
    if (n != eq || m != v.size() - eq - 1 || robot > 0xffffffffUL || !(t >= 0.0) || !std::isfinite(t))
      return std::nullopt;
    return std::pair{static_cast<RobotId>(robot), t};
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

int RunReferenceCommand(const app::ProcessOptions& po, const std::string& datasets, const std::string& loss,
                        double loss_scale, bool no_known_pose, bool no_known_starts, bool check_start,
                        const std::vector<std::string>& until, const std::string& out_path) {
  const std::optional<Scenario> sc = app::LoadScenarioOrReport("mapmesh-lab", po);
  if (!sc) return 2;
  lab::ReferenceOptions options;
  options.datasets_root = ResolveDatasetsRoot(datasets, app::DefaultDatasetsRoot());
  options.known_pose = !no_known_pose;
  options.check_start = check_start;
  options.known_starts = !no_known_starts;
  for (const std::string& u : until) {
    const auto [robot, t] = *ParseUntil(u);
    const bool in_run = std::any_of(sc->robots.begin(), sc->robots.end(),
                                    [&](const RobotSpec& r) { return r.id == robot; });
    if (!in_run || options.until.contains(robot)) {
      std::fprintf(stderr, "mapmesh-lab: --until %s: %s\n", u.c_str(),
                   in_run ? "that robot's time is given twice" : "no such robot in the scenario");
      return 2;
    }
    options.until[robot] = t;
  }
  if (loss == "none") options.robust = RobustKernel{};
  if (loss == "huber") options.robust = RobustKernel{RobustLoss::kHuber, loss_scale > 0 ? loss_scale : 1.345};
  if (loss == "cauchy") options.robust = RobustKernel{RobustLoss::kCauchy, loss_scale > 0 ? loss_scale : 2.0};
  const lab::Reference r = lab::ComputeReference(*sc, options);
  const io::json j = ReferenceJson(r);
  if (out_path.empty()) {
    std::printf("%s\n", j.dump(1).c_str());
  } else {
    io::WriteJsonAtomic(out_path, j);
  }
  if (!r.available) {
    std::fprintf(stderr, "mapmesh-lab: no reference for %s: %s\n", sc->name.c_str(), r.why_none.c_str());
    return 0;
  }
  auto line = [](const char* what, const lab::ReferenceMap& m) {
    std::fprintf(stderr, "%-12s %4d landmarks  %.4f m after a rigid fit  NEES %.2f  %s in %.2f s\n", what, m.landmarks,
                 m.rmse_aligned_m, m.nees_mean, m.solution.report.converged ? "converged" : "NOT converged", m.solve_s);
  };
  line("central", r.central);
  const BatchSolution& fair = r.central.solution;
  if (fair.components.size() > 1) {
    std::string robots;
    for (std::size_t k = 1; k < fair.components.size(); ++k) {
      for (RobotId id : fair.components[k].robots) robots += " " + std::to_string(id);
    }
    std::fprintf(stderr, "central: %zu components, each solved in its own frame; not connected to the largest:%s\n",
                 fair.components.size(), robots.c_str());
  }
  if (r.central.from_truth) {
    std::fprintf(stderr, "central: cost %.6f from the robots' own solutions, %.6f from the truth\n",
                 fair.report.final_cost, r.central.from_truth->final_cost);
  }
  if (r.has_known_starts) line("known starts", r.central_known_starts);
  if (r.known_pose) line("known poses", *r.known_pose);
  for (const auto& [id, m] : r.own) line(("robot " + std::to_string(id)).c_str(), m);
  for (const auto& [id, m] : r.own_known_pose) line(("known " + std::to_string(id)).c_str(), m);
  std::fprintf(stderr, "loss %s; %.2f s in all\n", r.loss.c_str(), r.total_s);
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
  slam->add_option("--seeds", seeds, "Monte Carlo runs (seeds first-seed, first-seed + 1, ...)")
      ->check(CLI::PositiveNumber);
  slam->add_option("--first-seed", first_seed, "first seed (default: the scenario's, for one run; 0 otherwise)");
  slam->add_flag("--hide-signatures", hide, "give the estimator unidentified observations and score its associations");
  slam->add_option("--datasets", datasets, "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  slam->add_option("--csv", csv, "write the CSV here (default: stdout)");
  slam->add_option("--trace", trace, "also write each robot's per-scan pose errors to CSVs in this directory");
  lab::MapPairOptions maps;
  AlignmentOptions align;
  std::string matcher = "sorted", distance = "mahalanobis";
  int trials = 100;
  std::uint64_t align_seed = 1;
  std::string align_csv;
  CLI::App* al = cli.add_subcommand("align", "align synthetic map pairs (thesis 5.1.1): success, accuracy, time");
  al->add_option("--landmarks", maps.landmarks, "landmarks per map")->check(CLI::PositiveNumber);
  al->add_option("--overlap", maps.overlap, "share of each map the other also holds (0: disjoint)")
      ->check(CLI::Range(0.0, 1.0));
  al->add_option("--sigma", maps.sigma_m, "landmark noise (m)")->check(CLI::NonNegativeNumber);
  al->add_option("--density", maps.density_per_m2, "landmarks per square metre")->check(CLI::PositiveNumber);
  al->add_option("--spacing", maps.min_spacing_m, "minimum distance between landmarks (m)")
      ->check(CLI::NonNegativeNumber);
  al->add_option("--trials", trials, "map pairs")->check(CLI::PositiveNumber);
  al->add_option("--seed", align_seed, "seed of the first pair");
  al->add_option("--matcher", matcher, "sorted | thesis")->check(CLI::IsMember({"sorted", "thesis"}));
  al->add_option("--distance", distance, "mahalanobis | euclidean")->check(CLI::IsMember({"mahalanobis", "euclidean"}));
  al->add_option("--gate", align.euclidean_gate_m, "Euclidean consensus gate (m)");
  al->add_option("--min-inliers", align.min_inliers, "fewer inliers: rejected");
  al->add_option("--csv", align_csv, "write the CSV here (default: stdout)");
  app::ProcessOptions pairs_po;
  std::string pairs_csv, pairs_datasets;
  CLI::App* pairs = cli.add_subcommand(
      "pairs", "run every robot's SLAM, then align every pair of robots by map overlap and by rendezvous");
  app::AddScenarioOptions(*pairs, pairs_po);
  pairs->add_option("--datasets", pairs_datasets,
                    "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  pairs->add_option("--csv", pairs_csv, "write the CSV here (default: stdout)");
  std::vector<std::string> pairs_searches{"ransac"};
  pairs
      ->add_option("--align-search", pairs_searches,
                   "transform searches to align every pair with, each in turn on the same maps: ransac, arw, its")
      ->delimiter(',')
      ->check(CLI::IsMember({"ransac", "arw", "its"}));
  lab::SearchComparisonOptions search_so;
  search_so.maps.landmarks = 200;
  search_so.maps.density_per_m2 = 0.08;
  search_so.maps.sigma_m = 0.1;
  std::string search_csv, search_distance = "mahalanobis";
  CLI::App* search = cli.add_subcommand(
      "search",
      "RANSAC vs adaptive random walk vs iterative translation search (thesis Tables 3-4) on the same synthetic "
      "map pairs at several overlaps: success, errors, time");
  search->add_option("--landmarks", search_so.maps.landmarks, "landmarks per map")->check(CLI::PositiveNumber);
  search->add_option("--overlaps", search_so.overlaps, "overlaps (0: disjoint pairs)")
      ->delimiter(',')
      ->check(CLI::Range(0.0, 1.0));
  search->add_option("--sigma", search_so.maps.sigma_m, "landmark noise (m)")->check(CLI::NonNegativeNumber);
  search->add_option("--density", search_so.maps.density_per_m2, "landmarks per square metre")
      ->check(CLI::PositiveNumber);
  search->add_option("--trials", search_so.trials, "map pairs per overlap")->check(CLI::PositiveNumber);
  search->add_option("--seed", search_so.seed, "seed of the first pair");
  search->add_option("--distance", search_distance, "mahalanobis | euclidean")
      ->check(CLI::IsMember({"mahalanobis", "euclidean"}));
  search->add_option("--csv", search_csv, "write the CSV here (default: stdout)");
  lab::ThesisAlignmentOptions ta;
  std::string ta_dir = "lab-out/alignment";
  CLI::App* thesis_align = cli.add_subcommand(
      "thesis-align", "the thesis's alignment experiments (Figs. 45-46, 48-53): CSVs for scripts/plots/alignment.py");
  thesis_align->add_option("--out", ta_dir, "directory for the CSVs");
  thesis_align->add_option("--trials", ta.trials, "runs per point of each curve")->check(CLI::PositiveNumber);
  thesis_align->add_option("--seed", ta.seed, "first seed");
  app::ProcessOptions fusion_po;
  std::string fusion_param, fusion_csv, fusion_datasets;
  std::vector<double> fusion_values;
  lab::FusionSweepOptions fusion_so;
  CLI::App* fusion = cli.add_subcommand(
      "fusion", "sweep a scenario key; fuse robot 2's map into robot 1's global map with every estimator (thesis 5.2)");
  app::AddScenarioOptions(*fusion, fusion_po);
  fusion->add_option("--param", fusion_param, "the scenario key to sweep, e.g. robots.list[1].sensor.sigma_bearing_deg")
      ->required();
  fusion->add_option("--values", fusion_values, "its values (comma-separated)")->required()->delimiter(',');
  fusion->add_option("--seeds", fusion_so.seeds, "Monte Carlo runs per value")->check(CLI::PositiveNumber);
  fusion->add_option("--first-seed", fusion_so.first_seed, "seed of the first run");
  fusion->add_option("--threads", fusion_so.threads, "worker threads (default: the machine's cores)")
      ->check(CLI::NonNegativeNumber);
  fusion->add_flag("--oracle-alignment", fusion_so.trial.oracle_alignment,
                   "use the true transform instead of aligning the maps");
  fusion->add_option("--datasets", fusion_datasets,
                     "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  fusion->add_option("--csv", fusion_csv, "write the CSV here (default: stdout)");
  lab::ThesisFusionOptions tf;
  std::string tf_dir = "lab-out/fusion", tf_datasets;
  CLI::App* thesis_fusion = cli.add_subcommand(
      "thesis-fusion",
      "the thesis's fusion experiments (Figs. 61-62, 64-65, 72-73, Table 7): CSVs for scripts/plots/fusion.py");
  thesis_fusion->add_option("--out", tf_dir, "directory for the CSVs");
  thesis_fusion
      ->add_option("--seeds", tf.seeds,
                   "Monte Carlo runs per point (default: each experiment's, the thesis's count where it gives one)")
      ->check(CLI::PositiveNumber);
  thesis_fusion->add_option("--first-seed", tf.first_seed, "seed of the first run");
  thesis_fusion->add_option("--threads", tf.threads, "worker threads (default: the machine's cores)")
      ->check(CLI::NonNegativeNumber);
  thesis_fusion
      ->add_option(
          "--only", tf.only,
          "run only these: bearing, velocity, range, victoria (the real replay), low_overlap, vp_bearing, "
          "vp_velocity, vp_range, vp_table7 (the simulated Victoria Park), fig58 (one run's covariance ellipses)")
      ->delimiter(',')
      ->check(CLI::IsMember(lab::kThesisFusionExperiments));
  thesis_fusion->add_flag("--oracle-alignment", tf.oracle_alignment,
                          "use the true transforms instead of aligning the maps");
  thesis_fusion->add_option("--datasets", tf_datasets,
                            "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  std::string vw_out = MAPMESH_SOURCE_DIR "/scenarios", vw_datasets;
  lab::VictoriaWorldOptions vw;
  CLI::App* victoria_world = cli.add_subcommand(
      "victoria-world",
      "derive the simulated Victoria Park (thesis 4.2, 5.3-5.4) from the dataset: OUT/victoria_sim.yaml and "
      "OUT/data/victoria_sim_landmarks.csv");
  victoria_world->add_option("--out", vw_out, "directory for the scenario (default: the checkout's scenarios/)");
  victoria_world->add_option("--datasets", vw_datasets,
                             "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  victoria_world->add_option("--segments", vw.segments, "disjoint time spans of the run")->check(CLI::Range(2, 20));
  victoria_world->add_option("--robots", vw.robots, "spans kept (by the landmarks they share)")
      ->check(CLI::Range(2, 20));
  app::ProcessOptions bus_po;
  std::vector<std::string> bus_kills, bus_restarts;
  std::string bus_datasets;
  CLI::App* bus = cli.add_subcommand(
      "bus", "run a scenario's agents in one process over an in-memory bus: maps, alignments, fusion");
  app::AddScenarioOptions(*bus, bus_po);
  bus->add_option("--kill", bus_kills, "kill agent ID at scenario time T (ID@T, repeatable)");
  bus->add_option("--restart", bus_restarts, "restart agent ID at T from its last checkpoint (ID@T, repeatable)");
  bus->add_option("--datasets", bus_datasets, "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  std::string bus_out;
  bus->add_option("--out", bus_out,
                  "also write each agent's final maps and trajectory to OUT/agent_<id>/ as a swarm run does");
  app::ProcessOptions ref_po;
  std::string ref_datasets, ref_loss = "auto", ref_out;
  double ref_loss_scale = 0.0;
  bool ref_no_known = false, ref_no_known_starts = false, ref_check_start = false;
  std::vector<std::string> ref_until;
  CLI::App* reference = cli.add_subcommand(
      "reference",
      "the limit of a scenario's data: the centralized batch optimum, each robot's own batch optimum and the "
      "known-pose map, scored against the truth (JSON; docs/EXPERIMENTS.md \"The limit\")");
  app::AddScenarioOptions(*reference, ref_po);
  reference->add_option("--datasets", ref_datasets,
                        "datasets root (default: $MAPMESH_DATASETS, else ../shared/datasets)");
  reference
      ->add_option("--loss", ref_loss,
                   "loss on each observation: auto (none for simulated worlds, cauchy for datasets), none, "
                   "huber, cauchy")
      ->check(CLI::IsMember({"auto", "none", "huber", "cauchy"}));
  reference
      ->add_option("--loss-scale", ref_loss_scale,
                   "the loss's scale in standard deviations (default: huber 1.345, cauchy 2)")
      ->check(CLI::PositiveNumber);
  reference->add_flag("--no-known-pose", ref_no_known, "skip the known-pose map");
  reference->add_flag("--no-known-starts", ref_no_known_starts,
                      "skip the centralized optimum with every true start (central_known_starts: null)");
  reference->add_flag("--check-start", ref_check_start,
                      "also solve the fair optimum from the truth and give its cost (central.from_truth): the solve "
                      "from the robots' own solutions should reach it");
  reference
      ->add_option("--until", ref_until,
                   "ROBOT=T: that robot's data up to scenario time T only (repeatable; the information that "
                   "reached one agent)")
      ->check([](const std::string& v) -> std::string {
        return ParseUntil(v) ? "" : "expected ROBOT=T (a robot id and a time in seconds, not negative)";
      });
  reference->add_option("--out", ref_out, "write the JSON here (default: stdout)");
  if (auto code = app::ParseArgs(cli, "mapmesh-lab", argc, argv)) return *code;
  if (reference->parsed())
    return RunReferenceCommand(ref_po, ref_datasets, ref_loss, ref_loss_scale, ref_no_known, ref_no_known_starts,
                               ref_check_start, ref_until, ref_out);
  if (victoria_world->parsed()) return RunVictoriaWorldCommand(vw_out, vw_datasets, vw);
  if (bus->parsed()) return RunBusCommand(bus_po, bus_kills, bus_restarts, bus_datasets, bus_out);
  if (thesis_fusion->parsed()) {
    tf.scenarios_dir = MAPMESH_SOURCE_DIR "/scenarios";
    tf.datasets_root = ResolveDatasetsRoot(tf_datasets, app::DefaultDatasetsRoot());
    lab::RunThesisFusion(tf_dir, tf);
    std::fprintf(stderr, "mapmesh-lab: CSVs in %s (plot: /usr/bin/python3 scripts/plots/fusion.py %s)\n",
                 tf_dir.c_str(), tf_dir.c_str());
    return 0;
  }
  if (fusion->parsed())
    return RunFusionCommand(fusion_po, fusion_param, fusion_values, fusion_so, fusion_datasets, fusion_csv);
  if (thesis_align->parsed()) {
    lab::RunThesisAlignment(ta_dir, ta);
    std::fprintf(stderr, "mapmesh-lab: CSVs in %s (plot: /usr/bin/python3 scripts/plots/alignment.py %s)\n",
                 ta_dir.c_str(), ta_dir.c_str());
    return 0;
  }
  if (pairs->parsed()) return RunPairsCommand(pairs_po, pairs_datasets, pairs_csv, pairs_searches);
  if (search->parsed()) {
    AlignmentOptions search_align;
    search_align.distance = search_distance == "euclidean" ? ConsensusDistance::kEuclidean
                                                           : ConsensusDistance::kMahalanobis;
    return RunSearchCommand(search_so, search_align, search_csv);
  }
  if (al->parsed()) {
    align.matcher = matcher == "thesis" ? TriangleMatcher::kThesisSimilarity : TriangleMatcher::kSortedSides;
    align.distance = distance == "euclidean" ? ConsensusDistance::kEuclidean : ConsensusDistance::kMahalanobis;
    return RunAlignCommand(maps, align, trials, align_seed, align_csv);
  }
  if (slam->parsed()) return RunSlamCommand(po, seeds, first_seed, hide, datasets, csv, trace);
  return 2;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-lab", [&] { return mapmesh::Run(argc, argv); });
}
