#pragma once
// The parts of map alignment that triangle matching (triangle_matching.cc) and the RANSAC and
// verification (map_alignment.cc) share: the landmarks alignment can use, the maps as it
// compares them, pair distances, and the weighted fit that concludes every alignment with its
// acceptance tests. Internal to common/merge; the API is map_alignment.h.

#include <Eigen/Core>
#include <tuple>
#include <utility>
#include <vector>

#include "common/geometry/covariance2.h"
#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/merge/map_alignment.h"
#include "common/merge/point_grid.h"

namespace mapmesh::alignment_detail {

// The landmarks of a map that alignment can use.
struct Usable {
  std::vector<int> index;  // into the map's landmarks
  std::vector<Eigen::Vector2d> points;
  std::vector<double> sigma;  // sqrt of the covariance's largest eigenvalue
  double max_sigma = 0.0;
};

using ::mapmesh::LargestSigma;  // common/geometry/covariance2.h

Usable UsableLandmarks(const LandmarkMap& m);

// The map as alignment compares it (consensus, matching, the tests): where the map's shape
// precision is known and tighter than a landmark's marginal, the landmark counts with that
// precision (isotropic), since a rigid transform absorbs the pose error that the marginals
// mostly hold. With every_landmark (the fit), all landmarks count with it: the marginals would
// weigh the landmarks near the map's origin up to a hundred times more than the rest (a SLAM
// map's marginals grow with the distance travelled) and the fit would follow those few; alike,
// it is the least-squares fit of the shapes (line of three: robot 3's landmarks placed at
// 0.031 m by the marginals' fit, 0.017 m by this one, on the final maps). Shape precision never
// counts below the floor: landmarks are not points, and real maps' shapes are rarely as good as
// their filters believe (MRCLAM: 2-4 cm claimed, 4-11 cm found).
LandmarkMap ForAlignment(const LandmarkMap& m, double floor_m, bool every_landmark = false);

// One-to-one pairs, closest first.
std::vector<std::pair<int, int>> OneToOne(std::vector<std::tuple<double, int, int>> scored);

// Residual a - T(b) of a pair and its squared Mahalanobis distance under T.
double PairD2(const Landmark& la, const Landmark& lb, const PoseMap2& t, Eigen::Vector2d* r = nullptr);

// Squared Mahalanobis (or Euclidean) distance of a pair under t, or infinity outside the gate.
double GatedD2(const Landmark& la, const Landmark& lb, const PoseMap2& t, const AlignmentOptions& o, double gate);

// RANSAC's consensus test over a fixed list of candidate pairs. A hypothesis's support is the
// landmarks its gated candidates pair, each counted once on each side (where candidates are
// dense, one landmark can sit in many compatible pairs); its cost, the sum of their distances.
class ConsensusScorer {
 public:
  struct Score {
    int support = 0;  // min(landmarks of a, landmarks of b) among the gated candidates
    int pairs = 0;    // gated candidates
    double cost = 0.0;
  };
  // a and b as alignment compares them (ForAlignment); all three are held by reference.
  ConsensusScorer(const LandmarkMap& a, const LandmarkMap& b, const std::vector<CandidatePair>& cand,
                  const AlignmentOptions& o);
  // Scores t; in (resized to the candidates) marks those within the gate.
  Score Evaluate(const PoseMap2& t, std::vector<char>& in);

 private:
  const LandmarkMap& a_;
  const LandmarkMap& b_;
  const std::vector<CandidatePair>& cand_;
  const AlignmentOptions& o_;
  double gate_;
  std::vector<int> stamp_a_, stamp_b_;
  int evaluation_ = 0;
};

// The one-to-one pairs of a's and b's usable landmarks (ua, ub; grid holds ua's points) that
// lie within the consensus gate at t, closest first; cost (optional) gets the sum of their
// squared distances. Guided matching, and the searches beside RANSAC (transform_search.h).
std::vector<std::pair<int, int>> GatedPairs(const LandmarkMap& a, const Usable& ua, const PointGrid2& grid,
                                            const LandmarkMap& b, const Usable& ub, const Pose2& t,
                                            const AlignmentOptions& o, double* cost = nullptr);

// From a transform and its first inliers: guided matching (optional), refinement, the
// transform's covariance and the acceptance tests. a and b are the maps as alignment compares
// them, a_in and b_in as given (for the fit's weights and the covariance).
void Conclude(const LandmarkMap& a_in, const LandmarkMap& b_in, const LandmarkMap& a, const LandmarkMap& b, Pose2 t,
              std::vector<std::pair<int, int>> inliers, const AlignmentOptions& o, bool guided, AlignmentResult& r);

}  // namespace mapmesh::alignment_detail
