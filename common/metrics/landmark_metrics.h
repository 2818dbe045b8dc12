#pragma once
// Map quality against ground truth: RMSE, NEES (thesis eq. 94), the consistent-landmark
// ratio at the 95 % chi-square bound, and coverage.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>

#include "common/geometry/pose2.h"

#include "common/map/landmark_map.h"
#include "common/types/messages.h"

namespace mapmesh {

// 95 % bound of a chi-square with 2 degrees of freedom.
inline constexpr double kChi2Dof2P95 = 5.991464547107979;

// NEES of one 2D estimate: e^T cov^-1 e (thesis eq. 94). Infinite when cov is singular.
double Nees(const Eigen::Vector2d& estimate, const Eigen::Matrix2d& cov, const Eigen::Vector2d& truth);

// Area of the covariance's one-sigma ellipse, pi sqrt(det) (thesis eq. 97); the 95 % ellipse
// drawn in plots (2.448 sigma) is 5.99 times larger.
double EllipseArea(const Eigen::Matrix2d& cov);

// Association quality against the truth: `predicted` holds, for each pairing an associator
// made, the true identities of its two sides (-1: no true counterpart); `possible` is the
// number of pairings the truth allows (landmarks both sides hold).
struct AssociationScore {
  int predicted = 0, correct = 0, possible = 0;
  double precision = 1.0;  // correct / predicted (1 when nothing was predicted)
  double recall = 1.0;     // correct / possible (1 when nothing was possible)
};
AssociationScore ScoreAssociations(const std::vector<std::pair<int, int>>& predicted, int possible);

// Each estimated landmark's true counterpart (index into truth), or -1.
// A landmark with a signature is matched to that true landmark; one without is matched to
// the nearest true landmark within gate_m (each true landmark at most once, closest first).
std::vector<int> MatchToTruth(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth, double gate_m);

struct MapQuality {
  bool evaluated = true;           // false: the map could not be placed in the truth frame
  bool aligned = false;            // placed by a rigid fit to the truth rather than a known origin
  int landmarks = 0;               // landmarks in the map
  int matched = 0;                 // of which have a true counterpart
  double rmse_m = 0.0;             // over matched landmarks
  double nees_mean = 0.0;          // over matched landmarks
  double consistent_ratio = 0.0;   // share of matched landmarks with NEES below kChi2Dof2P95
  double coverage = 0.0;           // share of `seen` true landmarks that the map contains
  std::vector<int> truth_matched;  // the true landmarks the map holds (indices into truth, increasing)
  std::optional<Pose2> fit;        // EvaluateFittedMap: the map frame's pose in the world after the rigid fit
};

// Quality of a map already expressed in the truth frame. seen lists the true landmarks that
// any robot observed (the coverage denominator); empty means all of them.
MapQuality EvaluateMap(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth, const std::vector<int>& seen,
                       double gate_m = 2.0);

// Where a map's frame really lies in the world: the least-squares rigid fit of its landmarks to
// the (finite) true ones they carry the signature of (needs two); nullopt without signatures.
std::optional<Pose2> MapFrameInWorld(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth);

// Quality of a map given in its own frame. It is moved into the truth frame by `origin` (the
// true pose of the frame) when known; otherwise by EvaluateFittedMap, and then aligned is true.
MapQuality EvaluateOwnFrameMap(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth,
                               const std::vector<int>& seen, const std::optional<Pose2>& origin, double gate_m = 2.0);

// Quality of a map after the least-squares rigid fit of the whole map to the truth (the scoring
// convention's rmse_aligned_m): every landmark matched to the truth (by signature, else the
// nearest true landmark within gate_m) takes part, relayed ones without signatures included.
// The fit starts from `initial` (where the map frame is thought to lie), else from
// MapFrameInWorld, and alternates matching and fitting until the matches stop changing.
// evaluated is false when there is no start or fewer than two landmarks match.
MapQuality EvaluateFittedMap(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth,
                             const std::vector<int>& seen, const std::optional<Pose2>& initial, double gate_m = 2.0);

// Quality of a map whose landmarks lie in frames of their own, one per part (`part_of`, by
// signature: a centralized optimum's components, which nothing in the data ties together):
// each part after its own rigid fit, as EvaluateFittedMap, the figures pooled over the parts
// fitted (a part with fewer than two matched landmarks is left out). A landmark `part_of` does
// not name is in part -1. With a single part, EvaluateFittedMap itself; fit is the largest
// part's.
MapQuality EvaluateFittedParts(const LandmarkMap& map, const std::map<std::int32_t, int>& part_of,
                               const std::vector<Eigen::Vector2d>& truth, const std::vector<int>& seen,
                               const std::optional<Pose2>& initial, double gate_m = 2.0);

// A local map's landmark: robot, incarnation, landmark id (a global map's origins name them).
using LocalLandmark = std::tuple<RobotId, std::uint32_t, std::uint32_t>;
// Local landmarks' identities as their robots' sensors gave them (their signatures).
using LocalSignatures = std::map<LocalLandmark, std::int32_t>;

// What SignByOrigins did.
struct OriginSigning {
  int signed_count = 0;  // landmarks without a signature given one by their origins
  int mixed = 0;         // landmarks whose origins, the holder's included, name different signatures
};

// Gives each landmark of a global map that carries no signature (a peer's: maps on the wire
// carry none) the signature its origins (`origins[i]`, the source landmarks fused into landmark
// i) have in `known`, so that it is scored against the landmark its robots' sensors measured
// rather than the nearest true one (in rows 1.5 m apart, a neighbour's, once a map's frame
// drifts). Origins `known` lacks are skipped. A landmark whose known origins name different
// signatures (a false association, or a pairing the join dropped: its origins are the
// association's) counts in `mixed` and is not signed: it is matched by distance as before.
OriginSigning SignByOrigins(LandmarkMap& map, const std::vector<std::vector<LocalLandmark>>& origins,
                            const LocalSignatures& known);

// The landmarks of a map whose signature is among truth_indices (increasing): a reference map (whose
// signatures are the true landmarks' indices) on the landmarks another map holds.
LandmarkMap RestrictToTruth(const LandmarkMap& map, const std::vector<int>& truth_indices);

// The share of a reference map's landmarks (signatures: the true landmarks' indices) among
// truth_matched (increasing, MapQuality::truth_matched): with the optimum of what reached an
// agent, the coverage of what reached it (issue J2: every landmark that a robot whose data
// reached the agent saw before it did). nullopt when the reference has no signed landmark.
std::optional<double> CoverageOf(const LandmarkMap& reference, const std::vector<int>& truth_matched);

}  // namespace mapmesh
