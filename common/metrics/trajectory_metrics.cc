#include "common/metrics/trajectory_metrics.h"

#include <algorithm>
#include <cmath>

#include "common/geometry/pose2.h"
#include "common/geometry/rigid_fit.h"

namespace mapmesh {

TrajectoryError CompareTrajectory(const std::vector<TimedPosition>& estimate,
                                  const std::vector<TimedPosition>& reference, bool align, double max_gap_s) {
  TrajectoryError out;
  std::vector<Eigen::Vector2d> est, ref;
  std::vector<double> times;
  for (const TimedPosition& r : reference) {
    auto hi = std::lower_bound(estimate.begin(), estimate.end(), r.t,
                               [](const TimedPosition& a, double v) { return a.t < v; });
    if (hi == estimate.end() || hi == estimate.begin()) {
      if (hi != estimate.end() && hi->t == r.t) {
        est.push_back(hi->p);
        ref.push_back(r.p);
        times.push_back(r.t);
      }
      continue;
    }
    const auto lo = hi - 1;
    if (hi->t - lo->t > max_gap_s) continue;
    const double a = (r.t - lo->t) / (hi->t - lo->t);
    est.push_back(lo->p + a * (hi->p - lo->p));
    ref.push_back(r.p);
    times.push_back(r.t);
  }
  if (align) {
    const auto fit = FitRigid2D(est, ref);
    if (!fit) return out;
    for (auto& p : est) p = fit->Apply(p);
    out.aligned = true;
  }
  double se = 0.0;
  for (std::size_t i = 0; i < est.size(); ++i) {
    const double e = (est[i] - ref[i]).norm();
    out.errors_m.push_back(e);
    se += e * e;
  }
  out.times = std::move(times);
  out.samples = static_cast<int>(est.size());
  if (out.samples > 0) out.rmse_m = std::sqrt(se / out.samples);
  return out;
}

namespace {

// The estimate's pose at t, interpolated between the samples around it when they are at most
// max_gap_s apart; nullopt outside its span or in a longer gap.
std::optional<Pose2> CoveredPoseAt(const std::vector<PoseStamp>& track, double t, double max_gap_s) {
  const auto hi = std::lower_bound(track.begin(), track.end(), t, [](const PoseStamp& a, double v) { return a.t < v; });
  if (hi == track.end()) return std::nullopt;
  if (hi->t == t) return hi->pose;
  if (hi == track.begin() || hi->t - (hi - 1)->t > max_gap_s) return std::nullopt;
  const auto lo = hi - 1;
  return Interpolate(lo->pose, hi->pose, (t - lo->t) / (hi->t - lo->t));
}

}  // namespace

RelativeTrajectoryError CompareRelativePoses(
    const std::vector<PoseStamp>& estimate, const std::vector<PoseStamp>& reference, double delta_s, double max_gap_s) {
  RelativeTrajectoryError out;
  double se_t = 0.0, se_r = 0.0;
  std::size_t j = 0;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    j = std::max(j, i + 1);
    while (j < reference.size() && reference[j].t - reference[i].t < delta_s) ++j;
    if (j >= reference.size()) break;
    if (reference[j].t - reference[i].t > delta_s + max_gap_s) continue;
    const std::optional<Pose2> pi = CoveredPoseAt(estimate, reference[i].t, max_gap_s);
    const std::optional<Pose2> pj = CoveredPoseAt(estimate, reference[j].t, max_gap_s);
    if (!pi || !pj) continue;
    const Pose2 truth_motion = reference[i].pose.Inverse() * reference[j].pose;
    const Pose2 error = truth_motion.Inverse() * (pi->Inverse() * *pj);
    se_t += error.x * error.x + error.y * error.y;
    const double r = WrapAngle(error.theta);
    se_r += r * r;
    ++out.pairs;
  }
  if (out.pairs > 0) {
    out.translation_rmse_m = std::sqrt(se_t / out.pairs);
    out.rotation_rmse_rad = std::sqrt(se_r / out.pairs);
  }
  return out;
}

std::vector<TimedPosition> DropImplausibleFixes(const std::vector<TimedPosition>& fixes, double max_speed_mps) {
  std::vector<TimedPosition> kept;
  for (const TimedPosition& f : fixes) {
    if (!kept.empty()) {
      const double dt = f.t - kept.back().t;
      if (dt <= 0.0 || (f.p - kept.back().p).norm() > max_speed_mps * dt) continue;
    }
    kept.push_back(f);
  }
  return kept;
}

}  // namespace mapmesh

#include "common/geometry/pose2.h"
#include "common/geometry/pose_track.h"

namespace mapmesh {

TransformError CompareTransforms(const Pose2& estimate, const Pose2& truth, const Eigen::Vector2d& at) {
  return {(estimate.Apply(at) - truth.Apply(at)).norm(), std::abs(WrapAngle(estimate.theta - truth.theta))};
}

std::optional<Pose2> TruthAt(const std::vector<GroundTruth>& g, double t) {
  return PoseAlong(
      g, t, [](const GroundTruth& s) { return s.stamp; },
      [](const GroundTruth& s) {
        return Pose2{s.x, s.y, s.theta};
      });
}

}  // namespace mapmesh
