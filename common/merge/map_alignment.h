#pragma once
// Aligning two landmark maps whose frames are unknown to each other (thesis 3.3.2, after
// Cunningham's DDF-SAM): Delaunay triangles of each map, triangle matching to propose
// landmark pairs, RANSAC over those pairs with the closed-form two-point transform
// (eq. 57-59) and the adaptive iteration bound (eq. 63-66), least-squares refinement with a
// covariance for the transform, and acceptance rules meant to reject a wrong alignment rather
// than merge it: a minimum inlier count, a chi-square test on the inliers' residuals, and an
// ambiguity test (the best hypothesis must clearly beat any different one).

#include <Eigen/Core>
#include <optional>
#include <random>
#include <string_view>
#include <utility>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/merge/transform_search_options.h"

namespace mapmesh {

enum class TriangleMatcher {
  kSortedSides,       // sorted side lengths in a k-d tree, tolerances from the covariances; a match
                      // counts only inside a grown patch of adjacent consistent matches: O(T log T)
  kThesisSimilarity,  // thesis eq. 51-53: perimeter and area, s = exp(sum of squared differences) < tau: O(T1 T2)
};

enum class ConsensusDistance { kEuclidean, kMahalanobis };

// How the landmarks' errors within a map relate, for the transform's covariance.
enum class LandmarkErrors {
  kIndependent,         // each landmark's error on its own: n inliers give n times the information
  kUnknownCorrelation,  // as in a SLAM map, where every landmark shares the robot's pose error: the
                        // inlier constraints are combined by Covariance Intersection (equal weights),
                        // which is consistent for any correlation: n inliers give the information of one
};

struct AlignmentOptions {
  TriangleMatcher matcher = TriangleMatcher::kSortedSides;
  double side_tolerance_sigmas = 3.0;  // sorted sides: sides may differ by this many sigmas ...
  double min_side_tolerance_m = 0.1;   // ... and at least this much (SLAM covariances are often optimistic)
  double min_side_m = 0.3;             // triangles with a shorter side are not used
  int min_consistent_triangles = 2;    // sorted sides: a match counts only in a patch of this many adjacent,
                                       // consistent matches
  int patch_stop_triangles = 12;       // sorted sides: once a patch this large is found ...
  int seeds_after_patch = 100;         // ... this many more seed triangles look for a competitor, then the
                                       // search stops
  double patch_keep_ratio = 0.25;      // patches smaller than this share of the largest are dropped
  double thesis_tau = 1.6487;          // thesis similarity threshold (exp(0.5))
  ConsensusDistance distance = ConsensusDistance::kMahalanobis;
  double euclidean_gate_m = 2.0;       // Euclidean consensus gate (thesis default)
  double gate_probability = 0.99;      // Mahalanobis consensus: chi-square 2 dof quantile
  double success_probability = 0.999;  // RANSAC stops when an all-inlier sample was drawn with this probability
                                       // (eq. 63)
  int max_iterations = 5000;
  int min_inliers = 6;                  // fewer inliers: rejected
  double residual_probability = 0.999;  // chi-square test on the inliers' residuals ...
  double residual_tolerance = 1.5;      // ... with its bound scaled by this: real SLAM maps' covariances are
                                        // often optimistic (map NEES up to 3, Victoria Park), while a wrong
                                        // alignment's inliers spread over the whole gate (4.6 per pair at 99 %)
  double ambiguity_ratio = 0.7;         // a different hypothesis with this share of the best's support: ambiguous
  double same_alignment_overlap = 0.5;  // hypotheses sharing this share of the smaller one's inlier pairs are one
  bool guided_matching = true;          // after RANSAC, look for inliers among all landmarks, not only candidates
  double coverage_radius_m = 2.5;       // a moved landmark of B within this of one of A's lies where A has mapped ...
  double min_overlap_ratio = 0.3;       // ... and at least this share of those must be inliers
  LandmarkErrors landmark_errors = LandmarkErrors::kUnknownCorrelation;  // for the transform's covariance
  double min_shape_sigma_m = 0.1;  // maps that report their shape precision (LandmarkMap::shape_sigma_m)
                                   // are compared with it (and fitted with it, every landmark alike), but
                                   // never below this
  TransformSearch search = TransformSearch::kRansac;  // how AlignMaps searches (transform_search.h)
  OverlapHeuristicOptions overlap;                    // arw and its: the overlap heuristic Delta
  RandomWalkOptions arw;
  TranslationSearchOptions its;
};

// A proposed correspondence: landmark a of map A and landmark b of map B, with the number
// of matched triangles that proposed it.
struct CandidatePair {
  int a = 0;
  int b = 0;
  int votes = 1;
};

enum class AlignmentVerdict {
  kAccepted = 0,
  kTooFewLandmarks,  // fewer than 3 usable landmarks in a map
  kNoTriangles,      // a map's landmarks are collinear (or too close together)
  kNoCandidates,     // no triangle of one map looks like a triangle of the other
  kTooFewInliers,
  kResidualsTooLarge,    // the inliers do not fit the transform as their covariances say
  kAmbiguous,            // another, different transform is nearly as well supported
  kInconsistentOverlap,  // where the transform lays B over A's mapped area, most of B's landmarks find no partner
  kDegenerate,           // the inliers do not determine the transform (collinear, or singular covariances)
};
std::string_view ToString(AlignmentVerdict v);

struct AlignmentResult {
  AlignmentVerdict verdict = AlignmentVerdict::kTooFewLandmarks;
  bool accepted() const { return verdict == AlignmentVerdict::kAccepted; }
  Pose2 transform;                                // maps B's frame into A's: p_A = transform.Apply(p_B)
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  // of (x, y, theta) of the transform
  std::vector<std::pair<int, int>> inliers;       // (index in A, index in B)
  int usable_a = 0, usable_b = 0;                 // landmarks with finite means and valid covariances
  int triangles_a = 0, triangles_b = 0;
  int candidates = 0;
  int best_patch = 0, patches = 0;  // sorted sides: largest patch of consistent triangle matches,
                                    // patches kept
  int iterations = 0;
  int best_support = 0;         // RANSAC consensus of the best hypothesis (candidates)
  int runner_up_support = 0;    // ... of the best hypothesis different from it
  int covered = 0;              // B's landmarks that the transform lays where A has mapped
  double residual_chi2 = 0.0;   // sum of the inliers' squared Mahalanobis residuals
  double residual_bound = 0.0;  // the chi-square bound it was tested against
};

// Candidate landmark pairs from matched Delaunay triangles. Indices refer to the maps'
// landmark vectors; unusable landmarks (non-finite, invalid covariance) never appear. rng
// orders the seed triangles (sorted sides).
std::vector<CandidatePair> MatchTriangles(const LandmarkMap& a, const LandmarkMap& b, const AlignmentOptions& options,
                                          std::mt19937_64& rng, AlignmentResult* stats = nullptr);

// RANSAC over candidate pairs, refinement and the acceptance tests.
AlignmentResult RansacAlign(const LandmarkMap& a, const LandmarkMap& b, const std::vector<CandidatePair>& candidates,
                            const AlignmentOptions& options, std::mt19937_64& rng);

// Checks a known transform against newer maps (cheap: no triangles, no RANSAC): guided matching
// from guess, refinement and the acceptance tests other than ambiguity. A wrong or
// corrupted map fails it.
AlignmentResult VerifyAlignment(const LandmarkMap& a, const LandmarkMap& b, const Pose2& guess,
                                const AlignmentOptions& options);

// The same for a guess known only to guess_cov (from other evidence, e.g. robots' sightings of
// each other), whose error may exceed the landmark gates: guided matching first runs with b laid
// over a at the guess and the guess's covariance added to every landmark of b, then the transform
// that gives is verified on the maps as they are. Ambiguity is not tested.
AlignmentResult VerifyUncertainAlignment(const LandmarkMap& a, const LandmarkMap& b, const Pose2& guess,
                                         const Eigen::Matrix3d& guess_cov, const AlignmentOptions& options);

// The whole pipeline: triangles, matching, RANSAC; or with options.search the adaptive random
// walk from the triangle matches, or the iterative translation search (no triangles):
// transform_search.h. Every search ends in the same refinement and acceptance tests.
AlignmentResult AlignMaps(const LandmarkMap& a, const LandmarkMap& b, const AlignmentOptions& options,
                          std::mt19937_64& rng);

}  // namespace mapmesh
