#include "lab/alignment_experiment.h"

#include <chrono>
#include <set>
#include <sstream>

#include "common/metrics/trajectory_metrics.h"

namespace mapmesh::lab {

std::vector<AlignTrial> RunAlignTrials(const MapPairOptions& maps, const AlignmentOptions& align, int trials,
                                       std::uint64_t seed) {
  using Clock = std::chrono::steady_clock;
  std::vector<AlignTrial> out;
  for (int k = 0; k < trials; ++k) {
    std::mt19937_64 rng(seed + static_cast<std::uint64_t>(k));
    const MapPair pair = MakeMapPair(maps, rng);
    AlignTrial t;
    t.trial = k;
    t.landmarks_a = static_cast<int>(pair.a.size());
    t.landmarks_b = static_cast<int>(pair.b.size());
    t.shared = static_cast<int>(pair.true_pairs.size());
    const std::set<std::pair<int, int>> truth(pair.true_pairs.begin(), pair.true_pairs.end());
    AlignmentResult stats;
    const auto t0 = Clock::now();
    const std::vector<CandidatePair> cand = MatchTriangles(pair.a, pair.b, align, rng, &stats);
    const auto t1 = Clock::now();
    AlignmentResult r;
    if (stats.usable_a < 3 || stats.usable_b < 3) {
      r.verdict = AlignmentVerdict::kTooFewLandmarks;
    } else if (stats.triangles_a == 0 || stats.triangles_b == 0) {
      r.verdict = AlignmentVerdict::kNoTriangles;
    } else {
      r = RansacAlign(pair.a, pair.b, cand, align, rng);
    }
    const auto t2 = Clock::now();
    t.match_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
    t.ransac_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
    t.verdict = r.verdict;
    t.candidates = static_cast<int>(cand.size());
    int true_cand = 0;
    for (const CandidatePair& c : cand) true_cand += truth.count({c.a, c.b});
    t.candidate_precision = cand.empty() ? 0.0 : static_cast<double>(true_cand) / cand.size();
    t.inliers = static_cast<int>(r.inliers.size());
    t.best_support = r.best_support;
    t.runner_up_support = r.runner_up_support;
    int true_inl = 0;
    for (const auto& p : r.inliers) true_inl += truth.count(p);
    t.inlier_precision = r.inliers.empty() ? 0.0 : static_cast<double>(true_inl) / r.inliers.size();
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const Landmark& l : pair.b.landmarks) centroid += l.mean;
    if (!pair.b.empty()) centroid /= static_cast<double>(pair.b.size());
    const TransformError e = CompareTransforms(r.transform, pair.truth, centroid);
    t.translation_error_m = e.translation_m;
    t.rotation_error_deg = RadToDeg(e.rotation_rad);
    t.correct = r.accepted() && e.translation_m <= 0.2 && t.rotation_error_deg <= 1.0;
    out.push_back(t);
  }
  return out;
}

std::string AlignCsvHeader() {
  return "trial,landmarks_a,landmarks_b,shared,verdict,correct,translation_error_m,rotation_error_deg,candidates,"
         "candidate_precision,inliers,inlier_precision,best_support,runner_up_support,match_ms,ransac_ms";
}

std::string AlignCsvRow(const AlignTrial& t) {
  std::ostringstream s;
  s << t.trial << ',' << t.landmarks_a << ',' << t.landmarks_b << ',' << t.shared << ',' << ToString(t.verdict) << ','
    << (t.correct ? 1 : 0) << ',' << t.translation_error_m << ',' << t.rotation_error_deg << ',' << t.candidates << ','
    << t.candidate_precision << ',' << t.inliers << ',' << t.inlier_precision << ',' << t.best_support << ','
    << t.runner_up_support << ',' << t.match_ms << ',' << t.ransac_ms;
  return s.str();
}

}  // namespace mapmesh::lab
