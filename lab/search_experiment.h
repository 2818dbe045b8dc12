#pragma once
// RANSAC, the adaptive random walk and the iterative translation search (thesis Tables 3-4;
// common/merge/transform_search.h) on the same seeded synthetic map pairs: success, accuracy
// and time of each, per overlap.

#include <cstdint>
#include <string>
#include <vector>

#include "common/merge/map_alignment.h"
#include "lab/synthetic_maps.h"

namespace mapmesh::lab {

struct SearchComparisonOptions {
  MapPairOptions maps;                               // overlap is taken from overlaps
  std::vector<double> overlaps{0.0, 0.3, 0.5, 0.8};  // 0: disjoint pairs, where every acceptance is wrong
  int trials = 200;                                  // map pairs per overlap
  std::uint64_t seed = 1;                            // of the first pair; the pairs are the same for every search
};

struct SearchTrial {
  double overlap = 0.0;
  int trial = 0;
  TransformSearch search = TransformSearch::kRansac;
  int landmarks_a = 0, landmarks_b = 0, shared = 0;
  AlignmentVerdict verdict = AlignmentVerdict::kTooFewLandmarks;
  bool correct = false;  // accepted, and within 0.2 m (at B's centroid) and 1 deg of the truth
  double translation_error_m = 0.0, rotation_error_deg = 0.0;
  int inliers = 0;
  double inlier_precision = 0.0;  // share of the inliers that are true pairs
  int best_support = 0, runner_up_support = 0;
  int iterations = 0;
  double ms = 0.0;  // wall time of AlignMaps (triangles included, where the search uses them)
};

// Every pair aligned by every search; progress to stderr.
std::vector<SearchTrial> RunSearchComparison(const SearchComparisonOptions& options, const AlignmentOptions& align);

std::string SearchCsvHeader();
std::string SearchCsvRow(const SearchTrial& t);

// One line per overlap and search: correct / accepted / wrong, errors of the accepted, time.
std::string SearchSummary(const std::vector<SearchTrial>& trials);

}  // namespace mapmesh::lab
