#pragma once
// Alignment between the robots of one run (real data): for every pair, map-overlap alignment
// of their local maps (by geometry only: signatures are not used) and rendezvous alignment
// from their mutual sightings, both scored against the true transform between their frames.

#include <string>
#include <vector>

#include "common/merge/map_alignment.h"
#include "lab/slam_experiment.h"

namespace mapmesh::lab {

struct PairResult {
  RobotId a = 0, b = 0;
  bool truth_known = false;
  // Map overlap.
  AlignmentVerdict verdict = AlignmentVerdict::kTooFewLandmarks;
  int inliers = 0;
  int best_support = 0, runner_up_support = 0;  // RANSAC consensus of the best and the best different hypothesis
  double residual_chi2 = 0.0, residual_bound = 0.0;
  int covered = 0;  // b's landmarks laid over a's mapped ground
  double map_translation_error_m = 0.0, map_rotation_error_deg = 0.0;
  TransformSearch search = TransformSearch::kRansac;  // options.search
  double map_ms = 0.0;                                // wall time of the map-overlap alignment
  // Rendezvous.
  int mutual_sightings = 0;                      // pairs of sightings less than 0.5 s apart
  double rendezvous_median_translation_m = 0.0;  // over the single-rendezvous estimates
  double rendezvous_median_rotation_deg = 0.0;
  double rendezvous_within_tolerance = 0.0;  // share within 0.2 m and 1 deg
};

// The true transform from b's map frame into a's: from rigid fits of both maps to the
// landmark truth (by signature) when possible, else from the true frame origins.
std::vector<PairResult> AlignPairs(const std::vector<SlamRunResult>& robots, const Scenario& scenario,
                                   const AlignmentOptions& options, std::mt19937_64& rng);

std::string PairsCsvHeader();
std::string PairsCsvRow(const PairResult& p);

}  // namespace mapmesh::lab
