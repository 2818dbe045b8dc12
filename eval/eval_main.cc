// mapmesh-eval: scores the maps of a run directory against its truth.json and prints one
// JSON document on stdout (scripts/swarm merges it into summary.json).

#include <cstdio>
#include <filesystem>

#include "common/app/process.h"
#include "common/io/run_files.h"
#include "common/metrics/landmark_metrics.h"
#include "common/metrics/trajectory_metrics.h"

namespace mapmesh {
namespace {

using io::json;

json QualityJson(const MapQuality& q) {
  if (!q.evaluated) {
    return {{"landmarks", q.landmarks}, {"matched", nullptr}, {"rmse_m", nullptr}, {"nees_mean", nullptr},
            {"consistent_ratio", nullptr}, {"coverage", nullptr}, {"frame", "unknown"}};
  }
  return {{"landmarks", q.landmarks},   {"matched", q.matched},
          {"rmse_m", q.rmse_m},         {"nees_mean", q.nees_mean},
          {"consistent_ratio", q.consistent_ratio}, {"coverage", q.coverage},
          {"frame", q.aligned ? "aligned" : "true_origin"}};
}

int Run(int argc, char** argv) {
  CLI::App cli{"mapmesh-eval: scores a run's maps against its ground truth (JSON on stdout)"};
  std::string run_dir;
  double gate_m = 2.0;
  cli.add_option("--run", run_dir, "run directory (holds truth.json and agent_<id>/)")->required();
  cli.add_option("--gate", gate_m, "metres: landmarks without a signature match the nearest true one within this");
  if (auto code = app::ParseArgs(cli, "mapmesh-eval", argc, argv)) return *code;
  const io::RunTruth truth = io::TruthFromJson(io::ReadJson(run_dir + "/truth.json"));
  json agents = json::object();
  for (const io::RobotTruth& robot : truth.robots) {
    const std::string dir = run_dir + "/agent_" + std::to_string(robot.id);
    json entry = json::object();
    // A map's frame is the robot's pose when its agent's session began: the start of the run,
    // or later for a restarted agent (its stats.json says when). Without a known pose the
    // map is rigidly aligned to the truth.
    std::optional<Pose2> origin = robot.start;
    if (std::filesystem::exists(dir + "/stats.json")) {
      const json stats = io::ReadJson(dir + "/stats.json");
      const json& t = stats.value("frame_origin_stamp", json());
      if (t.is_number() && truth.headings_known) origin = robot.PoseAt(t.get<double>());
      if (t.is_number() && !truth.headings_known) origin.reset();
    }
    for (const char* kind : {"local", "global"}) {
      const std::string path = dir + "/" + kind + "_map.json";
      if (!std::filesystem::exists(path)) continue;
      const LandmarkMap map = io::MapFromJson(io::ReadJson(path));
      entry[kind] = QualityJson(EvaluateOwnFrameMap(map, truth.landmarks, truth.seen, origin, gate_m));
      // The same map after a least-squares rigid fit to the truth, whatever its origin: the
      // error of its shape alone.
      const MapQuality aligned = EvaluateOwnFrameMap(map, truth.landmarks, truth.seen, std::nullopt, gate_m);
      entry[kind]["rmse_aligned_m"] = aligned.evaluated ? json(aligned.rmse_m) : json();
    }
    // The estimated trajectory against the true one: in the true frame when the origin is
    // known, else after a rigid fit (GPS glitches dropped).
    if (entry.contains("local") && std::filesystem::exists(dir + "/trajectory.json") && !robot.trajectory.empty()) {
      std::vector<TimedPosition> est, ref;
      const json traj = io::ReadJson(dir + "/trajectory.json");
      for (const auto& p : traj.at("poses")) {
        est.push_back({p.at(0).get<double>(), {p.at(1).get<double>(), p.at(2).get<double>()}});
      }
      for (const io::TruthSample& s : robot.trajectory) {
        if (origin) {
          const Pose2 rel = origin->Inverse() * s.pose;
          ref.push_back({s.t, {rel.x, rel.y}});
        } else {
          ref.push_back({s.t, {s.pose.x, s.pose.y}});
        }
      }
      const TrajectoryError e =
          origin ? CompareTrajectory(est, ref, false) : CompareTrajectory(est, DropImplausibleFixes(ref, 20.0), true);
      entry["local"]["trajectory_rmse_m"] = e.samples > 0 ? json(e.rmse_m) : json();
      entry["local"]["trajectory_frame"] = origin ? "true_origin" : "aligned";
    }
    agents[std::to_string(robot.id)] = entry;
  }
  std::printf("%s\n", json{{"agents", agents}, {"seen_landmarks", truth.seen.size()}}.dump(1).c_str());
  return 0;
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  return mapmesh::app::GuardedMain("mapmesh-eval", [&] { return mapmesh::Run(argc, argv); });
}
