#include "common/metrics/reference_metrics.h"

#include <cmath>
#include <limits>
#include <vector>

#include "common/metrics/landmark_metrics.h"

namespace mapmesh {

ReferenceQuality CompareToReference(const LandmarkMap& map, const LandmarkMap& reference, double gate_m,
                                    const AlignmentOptions& align, std::mt19937_64& rng,
                                    const std::optional<Pose2>& known_frame) {
  ReferenceQuality q;
  q.landmarks = static_cast<int>(map.size());
  q.reference_landmarks = static_cast<int>(reference.size());
  if (known_frame) {
    q.to_reference = *known_frame;
  } else {
    const AlignmentResult al = AlignMaps(WithoutSignatures(reference), WithoutSignatures(map), align, rng);
    if (!al.accepted()) return q;
    q.to_reference = al.transform;
  }
  q.aligned = true;
  const Pose2& to_ref = q.to_reference;
  const Eigen::Matrix2d rot = to_ref.Rotation();
  // Each map landmark's nearest reference landmark; each reference landmark keeps its nearest.
  const std::size_t none = std::numeric_limits<std::size_t>::max();
  std::vector<std::size_t> nearest(map.size(), none);
  std::vector<double> dist(map.size(), 0.0);
  std::vector<std::size_t> owner(reference.size(), none);
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Eigen::Vector2d p = to_ref.Apply(map.landmarks[i].mean);
    double best = gate_m;
    for (std::size_t j = 0; j < reference.size(); ++j) {
      const double d = (reference.landmarks[j].mean - p).norm();
      if (d <= best) {
        best = d;
        nearest[i] = j;
      }
    }
    dist[i] = best;
    if (nearest[i] == none) {
      ++q.extra;
    } else if (owner[nearest[i]] == none || dist[owner[nearest[i]]] > best) {
      owner[nearest[i]] = i;
    }
  }
  double sq = 0.0, nees = 0.0;
  for (std::size_t j = 0; j < reference.size(); ++j) {
    const std::size_t i = owner[j];
    if (i == none) continue;
    ++q.matched;
    sq += dist[i] * dist[i];
    const Landmark& l = map.landmarks[i];
    nees += Nees(to_ref.Apply(l.mean), rot * l.cov * rot.transpose() + reference.landmarks[j].cov,
                 reference.landmarks[j].mean);
  }
  q.duplicates = q.landmarks - q.extra - q.matched;
  if (q.matched > 0) {
    q.rmse_m = std::sqrt(sq / q.matched);
    q.nees_mean = nees / q.matched;
  }
  q.reference_coverage = reference.empty() ? 0.0
                                           : static_cast<double>(q.matched) / static_cast<double>(reference.size());
  return q;
}

}  // namespace mapmesh
