#include "common/metrics/landmark_metrics.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <set>
#include <tuple>

#include "common/geometry/rigid_fit.h"

namespace mapmesh {

double Nees(const Eigen::Vector2d& estimate, const Eigen::Matrix2d& cov, const Eigen::Vector2d& truth) {
  const double det = cov.determinant();
  if (!(det > 0.0) || !std::isfinite(det)) return std::numeric_limits<double>::infinity();
  const Eigen::Vector2d e = estimate - truth;
  return e.dot(cov.inverse() * e);
}

double EllipseArea(const Eigen::Matrix2d& cov) {
  return std::numbers::pi * std::sqrt(std::max(0.0, cov.determinant()));
}

AssociationScore ScoreAssociations(const std::vector<std::pair<int, int>>& predicted, int possible) {
  AssociationScore s;
  s.predicted = static_cast<int>(predicted.size());
  s.possible = possible;
  for (const auto& [a, b] : predicted) s.correct += a >= 0 && a == b;
  if (s.predicted > 0) s.precision = static_cast<double>(s.correct) / s.predicted;
  if (s.possible > 0) s.recall = static_cast<double>(s.correct) / s.possible;
  return s;
}

std::vector<int> MatchToTruth(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth, double gate_m) {
  std::vector<int> match(map.size(), -1);
  std::vector<bool> used(truth.size(), false);
  std::vector<std::tuple<double, std::size_t, std::size_t>> candidates;
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Landmark& l = map.landmarks[i];
    if (l.signature >= 0) {
      if (static_cast<std::size_t>(l.signature) < truth.size() && truth[l.signature].allFinite()) {
        match[i] = l.signature;
      }
      continue;
    }
    for (std::size_t j = 0; j < truth.size(); ++j) {
      if (!truth[j].allFinite()) continue;
      const double d = (l.mean - truth[j]).norm();
      if (d <= gate_m) candidates.emplace_back(d, i, j);
    }
  }
  for (int m : match) {
    if (m >= 0) used[m] = true;
  }
  std::sort(candidates.begin(), candidates.end());
  for (const auto& [d, i, j] : candidates) {
    if (match[i] >= 0 || used[j]) continue;
    match[i] = static_cast<int>(j);
    used[j] = true;
  }
  return match;
}

MapQuality EvaluateMap(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth, const std::vector<int>& seen,
                       double gate_m) {
  MapQuality q;
  q.landmarks = static_cast<int>(map.size());
  const std::vector<int> match = MatchToTruth(map, truth, gate_m);
  std::vector<bool> present(truth.size(), false);
  double se = 0.0, nees = 0.0;
  int consistent = 0;
  for (std::size_t i = 0; i < map.size(); ++i) {
    if (match[i] < 0) continue;
    const Landmark& l = map.landmarks[i];
    const Eigen::Vector2d& t = truth[match[i]];
    present[match[i]] = true;
    ++q.matched;
    se += (l.mean - t).squaredNorm();
    const double e = Nees(l.mean, l.cov, t);
    nees += e;
    if (e < kChi2Dof2P95) ++consistent;
  }
  if (q.matched > 0) {
    q.rmse_m = std::sqrt(se / q.matched);
    q.nees_mean = nees / q.matched;
    q.consistent_ratio = static_cast<double>(consistent) / q.matched;
  }
  std::vector<bool> counted(truth.size(), seen.empty());
  for (int j : seen) {
    if (j >= 0 && static_cast<std::size_t>(j) < truth.size()) counted[j] = true;
  }
  int denom = 0, covered = 0;
  for (std::size_t j = 0; j < truth.size(); ++j) {
    if (present[j]) q.truth_matched.push_back(static_cast<int>(j));
    if (!counted[j]) continue;
    ++denom;
    if (present[j]) ++covered;
  }
  q.coverage = denom > 0 ? static_cast<double>(covered) / denom : 0.0;
  return q;
}

std::optional<Pose2> MapFrameInWorld(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth) {
  std::vector<Eigen::Vector2d> src, dst;
  for (const Landmark& l : map.landmarks) {
    if (l.signature >= 0 && static_cast<std::size_t>(l.signature) < truth.size() && truth[l.signature].allFinite()) {
      src.push_back(l.mean);
      dst.push_back(truth[l.signature]);
    }
  }
  return FitRigid2D(src, dst);
}

MapQuality EvaluateOwnFrameMap(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth,
                               const std::vector<int>& seen, const std::optional<Pose2>& origin, double gate_m) {
  if (origin) return EvaluateMap(TransformMap(map, *origin), truth, seen, gate_m);
  return EvaluateFittedMap(map, truth, seen, std::nullopt, gate_m);
}

MapQuality EvaluateFittedMap(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth,
                             const std::vector<int>& seen, const std::optional<Pose2>& initial, double gate_m) {
  std::optional<Pose2> frame = initial ? initial : MapFrameInWorld(map, truth);
  std::vector<int> last;
  // Each round matches in the current placement and refits on the matches; a few rounds settle
  // it (the matches of signature-carrying landmarks never change).
  for (int round = 0; frame && round < 20; ++round) {
    const std::vector<int> match = MatchToTruth(TransformMap(map, *frame), truth, gate_m);
    if (match == last) break;
    std::vector<Eigen::Vector2d> src, dst;
    for (std::size_t i = 0; i < map.size(); ++i) {
      if (match[i] < 0) continue;
      src.push_back(map.landmarks[i].mean);
      dst.push_back(truth[match[i]]);
    }
    frame = FitRigid2D(src, dst);
    last = match;
  }
  if (!frame) {
    MapQuality q;
    q.evaluated = false;
    q.landmarks = static_cast<int>(map.size());
    return q;
  }
  MapQuality q = EvaluateMap(TransformMap(map, *frame), truth, seen, gate_m);
  q.aligned = true;
  q.fit = frame;
  return q;
}

MapQuality EvaluateFittedParts(const LandmarkMap& map, const std::map<std::int32_t, int>& part_of,
                               const std::vector<Eigen::Vector2d>& truth, const std::vector<int>& seen,
                               const std::optional<Pose2>& initial, double gate_m) {
  std::map<int, LandmarkMap> parts;
  for (const Landmark& l : map.landmarks) {
    const auto it = part_of.find(l.signature);
    LandmarkMap& part = parts[it != part_of.end() ? it->second : -1];
    part.shape_sigma_m = map.shape_sigma_m;
    part.landmarks.push_back(l);
  }
  if (parts.size() <= 1) return EvaluateFittedMap(map, truth, seen, initial, gate_m);
  LandmarkMap placed;  // every fitted part where its fit puts it
  placed.shape_sigma_m = map.shape_sigma_m;
  std::optional<Pose2> largest;
  std::size_t largest_size = 0;
  for (const auto& [k, part] : parts) {
    const MapQuality q = EvaluateFittedMap(part, truth, seen, initial, gate_m);
    if (!q.evaluated || !q.fit) continue;
    const LandmarkMap moved = TransformMap(part, *q.fit);
    placed.landmarks.insert(placed.landmarks.end(), moved.landmarks.begin(), moved.landmarks.end());
    if (part.size() > largest_size) {
      largest_size = part.size();
      largest = q.fit;
    }
  }
  if (!largest) {
    MapQuality q;
    q.evaluated = false;
    q.landmarks = static_cast<int>(map.size());
    return q;
  }
  MapQuality q = EvaluateMap(placed, truth, seen, gate_m);
  q.landmarks = static_cast<int>(map.size());
  q.aligned = true;
  q.fit = largest;
  return q;
}

LandmarkMap RestrictToTruth(const LandmarkMap& map, const std::vector<int>& truth_indices) {
  LandmarkMap out;
  out.shape_sigma_m = map.shape_sigma_m;
  for (const Landmark& l : map.landmarks) {
    if (std::binary_search(truth_indices.begin(), truth_indices.end(), l.signature)) out.landmarks.push_back(l);
  }
  return out;
}

std::optional<double> CoverageOf(const LandmarkMap& reference, const std::vector<int>& truth_matched) {
  std::set<std::int32_t> signatures;
  for (const Landmark& l : reference.landmarks) {
    if (l.signature >= 0) signatures.insert(l.signature);
  }
  if (signatures.empty()) return std::nullopt;
  const auto held = std::count_if(signatures.begin(), signatures.end(), [&](std::int32_t s) {
    return std::binary_search(truth_matched.begin(), truth_matched.end(), s);
  });
  return static_cast<double>(held) / static_cast<double>(signatures.size());
}

OriginSigning SignByOrigins(LandmarkMap& map, const std::vector<std::vector<LocalLandmark>>& origins,
                            const LocalSignatures& known) {
  OriginSigning out;
  for (std::size_t i = 0; i < map.size() && i < origins.size(); ++i) {
    std::int32_t& signature = map.landmarks[i].signature;
    bool mixed = false;
    std::int32_t first = signature;
    for (const auto& origin : origins[i]) {
      const auto it = known.find(origin);
      if (it == known.end() || it->second < 0) continue;
      if (first < 0) first = it->second;
      mixed = mixed || it->second != first;
    }
    if (mixed) ++out.mixed;
    if (signature < 0 && first >= 0 && !mixed) {
      signature = first;
      ++out.signed_count;
    }
  }
  return out;
}

}  // namespace mapmesh
