#include "lab/pairs_experiment.h"

#include <algorithm>
#include <chrono>
#include <sstream>

#include "common/map/landmark_map.h"
#include "common/merge/rendezvous.h"
#include "common/metrics/landmark_metrics.h"
#include "common/metrics/trajectory_metrics.h"

namespace mapmesh::lab {
namespace {

// Where the robot's map frame lies in the world: from the rigid fit of its map to the
// landmark truth (by signature) when it can be had, which is the frame the map is really in
// (heading drift before the first landmark rotates a map about its nominal origin), else
// from the true start pose.
std::optional<Pose2> FrameInWorld(const SlamRunResult& r) {
  if (auto fit = MapFrameInWorld(r.map, r.landmark_truth)) return fit;
  return r.origin_truth;
}

const SlamRunResult::PoseSample* PoseAt(const SlamRunResult& r, double t) {
  auto it = std::lower_bound(r.poses.begin(), r.poses.end(), t,
                             [](const SlamRunResult::PoseSample& p, double v) { return p.t < v; });
  if (it != r.poses.end() && std::abs(it->t - t) < 1e-9) return &*it;
  return nullptr;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

std::vector<PairResult> AlignPairs(const std::vector<SlamRunResult>& robots, const Scenario& sc,
                                   const AlignmentOptions& options, std::mt19937_64& rng) {
  std::vector<PairResult> out;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    for (std::size_t j = i + 1; j < robots.size(); ++j) {
      const SlamRunResult &ra = robots[i], &rb = robots[j];
      PairResult p;
      p.a = ra.robot;
      p.b = rb.robot;
      const auto fa = FrameInWorld(ra), fb = FrameInWorld(rb);
      p.truth_known = fa && fb;
      const Pose2 truth = p.truth_known ? fa->Inverse() * *fb : Pose2{};
      Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
      for (const Landmark& l : rb.map.landmarks) centroid += l.mean;
      if (!rb.map.empty()) centroid /= static_cast<double>(rb.map.size());

      // Map overlap, geometry only.
      const LandmarkMap ma = WithoutSignatures(ra.map), mb = WithoutSignatures(rb.map);
      const auto t0 = std::chrono::steady_clock::now();
      const AlignmentResult al = AlignMaps(ma, mb, options, rng);
      p.map_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      p.search = options.search;
      p.verdict = al.verdict;
      p.inliers = static_cast<int>(al.inliers.size());
      p.best_support = al.best_support;
      p.runner_up_support = al.runner_up_support;
      p.residual_chi2 = al.residual_chi2;
      p.residual_bound = al.residual_bound;
      p.covered = al.covered;
      if (p.truth_known) {
        const TransformError e = CompareTransforms(al.transform, truth, centroid);
        p.map_translation_error_m = e.translation_m;
        p.map_rotation_error_deg = RadToDeg(e.rotation_rad);
      }

      // Rendezvous: a's sighting of b paired with b's sighting of a within 0.5 s.
      const RobotSpec* sa = sc.FindRobot(ra.robot);
      const RobotSpec* sb = sc.FindRobot(rb.robot);
      std::vector<double> terr, rerr;
      int within = 0;
      for (const auto& s1 : ra.sightings) {
        if (s1.seen != rb.robot) continue;
        const SlamRunResult::Sighting* best = nullptr;
        for (const auto& s2 : rb.sightings) {
          if (s2.seen != ra.robot || std::abs(s2.t - s1.t) > 0.5) continue;
          if (!best || std::abs(s2.t - s1.t) < std::abs(best->t - s1.t)) best = &s2;
        }
        if (!best) continue;
        const auto* pa = PoseAt(ra, s1.t);
        const auto* pb = PoseAt(rb, best->t);
        if (!pa || !pb) continue;
        RendezvousInput in;
        in.pose1 = pa->pose;
        in.cov1 = pa->cov;
        in.pose2 = pb->pose;
        in.cov2 = pb->cov;
        in.range12 = s1.range;
        in.bearing12 = s1.bearing;
        in.range21 = best->range;
        in.bearing21 = best->bearing;
        in.sigma_range1 = sa->sensor.sigma_range_m;
        in.sigma_bearing1 = DegToRad(sa->sensor.sigma_bearing_deg);
        in.sigma_range2 = sb->sensor.sigma_range_m;
        in.sigma_bearing2 = DegToRad(sb->sensor.sigma_bearing_deg);
        const auto rv = RendezvousAlign(in);
        if (!rv) continue;
        ++p.mutual_sightings;
        if (p.truth_known) {
          const TransformError e = CompareTransforms(rv->transform, truth, centroid);
          terr.push_back(e.translation_m);
          rerr.push_back(RadToDeg(e.rotation_rad));
          within += e.translation_m <= 0.2 && RadToDeg(e.rotation_rad) <= 1.0;
        }
      }
      p.rendezvous_median_translation_m = Median(terr);
      p.rendezvous_median_rotation_deg = Median(rerr);
      p.rendezvous_within_tolerance = terr.empty() ? 0.0 : static_cast<double>(within) / terr.size();
      out.push_back(p);
    }
  }
  return out;
}

std::string PairsCsvHeader() {
  return "a,b,truth_known,map_verdict,map_inliers,best_support,runner_up_support,residual_chi2,residual_bound,covered,"
         "map_translation_error_m,map_rotation_error_deg,mutual_sightings,"
         "rendezvous_median_translation_m,rendezvous_median_rotation_deg,rendezvous_within_tolerance,align_search,"
         "map_ms";
}

std::string PairsCsvRow(const PairResult& p) {
  std::ostringstream s;
  s << p.a << ',' << p.b << ',' << p.truth_known << ',' << ToString(p.verdict) << ',' << p.inliers << ','
    << p.best_support << ',' << p.runner_up_support << ',' << p.residual_chi2 << ',' << p.residual_bound << ','
    << p.covered << ',' << p.map_translation_error_m << ',' << p.map_rotation_error_deg << ',' << p.mutual_sightings
    << ',' << p.rendezvous_median_translation_m << ',' << p.rendezvous_median_rotation_deg << ','
    << p.rendezvous_within_tolerance << ',' << NameOf(kTransformSearch, p.search) << ',' << p.map_ms;
  return s.str();
}

}  // namespace mapmesh::lab
