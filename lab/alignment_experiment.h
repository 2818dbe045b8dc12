#pragma once
// Alignment experiments on synthetic map pairs (thesis 5.1.1): success, accuracy and time of
// triangle matching and RANSAC.

#include <cstdint>
#include <string>
#include <vector>

#include "common/merge/map_alignment.h"
#include "lab/synthetic_maps.h"

namespace mapmesh::lab {

struct AlignTrial {
  int trial = 0;
  int landmarks_a = 0, landmarks_b = 0, shared = 0;
  AlignmentVerdict verdict = AlignmentVerdict::kTooFewLandmarks;
  bool correct = false;  // accepted, and within 0.2 m (at B's centroid) and 1 deg of the truth
  double translation_error_m = 0.0, rotation_error_deg = 0.0;
  int candidates = 0;
  double candidate_precision = 0.0;  // thesis "similarity success": share of candidate pairs that are true
  int inliers = 0;
  double inlier_precision = 0.0;                // share of the accepted inliers that are true pairs
  int best_support = 0, runner_up_support = 0;  // RANSAC consensus of the best and of the best different hypothesis
  double match_ms = 0.0, ransac_ms = 0.0;
};

// Runs `trials` seeded map pairs (seed + trial) through the whole pipeline.
std::vector<AlignTrial> RunAlignTrials(const MapPairOptions& maps, const AlignmentOptions& align, int trials,
                                       std::uint64_t seed);

std::string AlignCsvHeader();
std::string AlignCsvRow(const AlignTrial& t);

}  // namespace mapmesh::lab
