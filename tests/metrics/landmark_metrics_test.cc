#include "common/metrics/landmark_metrics.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <random>

#include "common/geometry/rigid_fit.h"

namespace mapmesh {
namespace {

TEST(Nees, IsTheMahalanobisSquare) {
  Eigen::Matrix2d cov;
  cov << 4, 0, 0, 1;
  EXPECT_DOUBLE_EQ(Nees({2, 1}, cov, {0, 0}), 1.0 + 1.0);
  EXPECT_TRUE(std::isinf(Nees({1, 0}, Eigen::Matrix2d::Zero(), {0, 0})));
}

TEST(Nees, AveragesTwoForAConsistentEstimator) {
  // Samples drawn from the stated covariance have mean NEES 2 (2 dof).
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0, 1);
  Eigen::Matrix2d cov;
  cov << 0.5, 0.2, 0.2, 0.3;
  const Eigen::Matrix2d l = cov.llt().matrixL();
  double sum = 0;
  const int kN = 20000;
  for (int i = 0; i < kN; ++i) sum += Nees(l * Eigen::Vector2d(n(rng), n(rng)), cov, {0, 0});
  EXPECT_NEAR(sum / kN, 2.0, 0.06);  // standard error of the mean is 2/sqrt(N) = 0.014
}

TEST(MatchToTruth, UsesSignaturesThenNearestWithinGate) {
  const std::vector<Eigen::Vector2d> truth{{0, 0}, {10, 0}, {20, 0}};
  LandmarkMap m;
  m.landmarks.push_back({0, 2, {0.1, 0}, Eigen::Matrix2d::Identity()});    // signature 2 wins
  m.landmarks.push_back({1, -1, {10.3, 0}, Eigen::Matrix2d::Identity()});  // nearest: 1
  m.landmarks.push_back({2, -1, {10.5, 0}, Eigen::Matrix2d::Identity()});  // 1 taken already
  m.landmarks.push_back({3, -1, {50, 0}, Eigen::Matrix2d::Identity()});    // outside the gate
  const auto match = MatchToTruth(m, truth, 2.0);
  EXPECT_EQ(match, (std::vector<int>{2, 1, -1, -1}));
}

TEST(EvaluateMap, RmseNeesAndCoverage) {
  const std::vector<Eigen::Vector2d> truth{{0, 0}, {10, 0}, {20, 0}, {30, 0}};
  LandmarkMap m;
  m.landmarks.push_back({0, 0, {0.3, 0.4}, Eigen::Matrix2d::Identity() * 0.25});  // err 0.5, nees 1
  m.landmarks.push_back({1, 1, {10, 0}, Eigen::Matrix2d::Identity()});            // err 0, nees 0
  m.landmarks.push_back({2, 2, {23, 0}, Eigen::Matrix2d::Identity()});            // err 3, nees 9
  const MapQuality q = EvaluateMap(m, truth, {0, 1, 2, 3});
  EXPECT_EQ(q.landmarks, 3);
  EXPECT_EQ(q.matched, 3);
  EXPECT_NEAR(q.rmse_m, std::sqrt((0.25 + 0 + 9) / 3), 1e-12);
  EXPECT_NEAR(q.nees_mean, (1.0 + 0.0 + 9.0) / 3, 1e-12);
  EXPECT_NEAR(q.consistent_ratio, 2.0 / 3, 1e-12);
  EXPECT_NEAR(q.coverage, 0.75, 1e-12);
  // Coverage counts only landmarks that were seen.
  EXPECT_NEAR(EvaluateMap(m, truth, {0, 3}).coverage, 0.5, 1e-12);
}

TEST(TransformMap, MovesMeansAndRotatesCovariances) {
  LandmarkMap m;
  Eigen::Matrix2d cov;
  cov << 4, 0, 0, 1;
  m.landmarks.push_back({0, -1, {1, 0}, cov});
  const LandmarkMap t = TransformMap(m, {5, 5, M_PI / 2});
  EXPECT_NEAR((t.landmarks[0].mean - Eigen::Vector2d(5, 6)).norm(), 0, 1e-12);
  EXPECT_NEAR(t.landmarks[0].cov(0, 0), 1, 1e-12);
  EXPECT_NEAR(t.landmarks[0].cov(1, 1), 4, 1e-12);
}

TEST(LandmarkMetrics, EllipseAreaIsPiSqrtDet) {
  EXPECT_NEAR(EllipseArea(Eigen::Matrix2d::Identity()), M_PI, 1e-12);
  Eigen::Matrix2d c;
  c << 4.0, 0.0, 0.0, 0.25;  // semi-axes 2 and 0.5
  EXPECT_NEAR(EllipseArea(c), M_PI * 2.0 * 0.5, 1e-12);
  // Rotation does not change the area.
  const double a = 0.7;
  Eigen::Matrix2d r;
  r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  EXPECT_NEAR(EllipseArea(r * c * r.transpose()), M_PI, 1e-12);
}

TEST(LandmarkMetrics, AssociationPrecisionAndRecall) {
  // Four pairings made: two right, one wrong, one with a side that has no true counterpart;
  // five were possible.
  const AssociationScore s = ScoreAssociations({{3, 3}, {5, 5}, {1, 2}, {-1, -1}}, 5);
  EXPECT_EQ(s.predicted, 4);
  EXPECT_EQ(s.correct, 2);
  EXPECT_DOUBLE_EQ(s.precision, 0.5);
  EXPECT_DOUBLE_EQ(s.recall, 0.4);
  const AssociationScore none = ScoreAssociations({}, 0);
  EXPECT_DOUBLE_EQ(none.precision, 1.0);
  EXPECT_DOUBLE_EQ(none.recall, 1.0);
}

TEST(MapFrameInWorld, RecoversTheFrameFromSignaturesOnly) {
  const std::vector<Eigen::Vector2d> truth = {{0, 0}, {4, 1}, {2, 5}, {-3, 2}};
  const Pose2 frame{1.5, -2.0, 0.7};
  LandmarkMap m;
  for (int i : {0, 2, 3}) {
    Landmark l;
    l.signature = i;
    l.mean = frame.Inverse().Apply(truth[i]);
    m.landmarks.push_back(l);
  }
  Landmark unknown;  // no signature: ignored
  unknown.mean = {100, 100};
  m.landmarks.push_back(unknown);
  const auto fit = MapFrameInWorld(m, truth);
  ASSERT_TRUE(fit.has_value());
  EXPECT_NEAR(fit->x, frame.x, 1e-9);
  EXPECT_NEAR(fit->y, frame.y, 1e-9);
  EXPECT_NEAR(fit->theta, frame.theta, 1e-9);
  m.landmarks.resize(1);
  m.landmarks.push_back(unknown);
  EXPECT_FALSE(MapFrameInWorld(m, truth).has_value());  // one signature is not enough
}

// A global map holds the agent's own landmarks (signatures) and relayed ones (none). The fit of
// the whole map uses both, so a relayed landmark's error weighs in the fit, and the fit needs no
// signature at all when it is given a start.
TEST(EvaluateFittedMap, FitsEveryMatchedLandmarkNotOnlyThoseWithSignatures) {
  const std::vector<Eigen::Vector2d> truth = {{0, 0}, {4, 1}, {2, 5}, {-3, 2}, {6, 6}, {-2, -4}};
  const Pose2 frame{1.5, -2.0, 0.7};
  LandmarkMap m;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    Landmark l;
    l.signature = i < 3 ? static_cast<int>(i) : -1;  // 3..5 relayed
    l.mean = frame.Inverse().Apply(truth[i]);
    l.cov = Eigen::Matrix2d::Identity() * 0.01;
    m.landmarks.push_back(l);
  }
  m.landmarks[5].mean += Eigen::Vector2d(0.6, 0.0);  // one relayed landmark 0.6 m off
  const MapQuality whole = EvaluateFittedMap(m, truth, {}, std::nullopt, 2.0);
  ASSERT_TRUE(whole.evaluated);
  EXPECT_TRUE(whole.aligned);
  EXPECT_EQ(whole.matched, 6);
  // Fitting on the signatures alone leaves the whole 0.6 m on one landmark: RMSE 0.6 / sqrt(6).
  // The whole-map fit spreads it, so its RMSE is strictly lower, and it is the least-squares
  // optimum: no small move of the frame lowers it.
  const MapQuality by_signatures = EvaluateMap(TransformMap(m, *MapFrameInWorld(m, truth)), truth, {}, 2.0);
  EXPECT_NEAR(by_signatures.rmse_m, 0.6 / std::sqrt(6.0), 1e-9);
  EXPECT_LT(whole.rmse_m, by_signatures.rmse_m - 0.01);
  std::vector<Eigen::Vector2d> src;
  for (const Landmark& l : m.landmarks) src.push_back(l.mean);
  const Pose2 best = *FitRigid2D(src, truth);
  EXPECT_NEAR(whole.rmse_m, EvaluateMap(TransformMap(m, best), truth, {}, 2.0).rmse_m, 1e-12);
  // The placement it reports (drawn by the report's "after rigid fit" panel) is that optimum.
  ASSERT_TRUE(whole.fit.has_value());
  EXPECT_NEAR(whole.fit->x, best.x, 1e-9);
  EXPECT_NEAR(whole.fit->y, best.y, 1e-9);
  EXPECT_NEAR(whole.fit->theta, best.theta, 1e-9);
  for (const Pose2& nudge : {Pose2{0.01, 0, 0}, Pose2{0, -0.01, 0}, Pose2{0, 0, 0.002}}) {
    EXPECT_GT(EvaluateMap(TransformMap(m, best * nudge), truth, {}, 2.0).rmse_m, whole.rmse_m);
  }
  // Without any signature the fit needs a start; given one 0.3 m and 0.05 rad off, it finds
  // the same optimum.
  for (Landmark& l : m.landmarks) l.signature = -1;
  EXPECT_FALSE(EvaluateFittedMap(m, truth, {}, std::nullopt, 2.0).evaluated);
  const MapQuality started = EvaluateFittedMap(m, truth, {}, frame * Pose2{0.3, -0.2, 0.05}, 2.0);
  ASSERT_TRUE(started.evaluated);
  EXPECT_EQ(started.matched, 6);
  EXPECT_NEAR(started.rmse_m, whole.rmse_m, 1e-9);
}

// A peer's landmarks in a global map carry no signature; their origins name the local
// landmarks their robots' sensors measured. In a row of trees 1.5 m apart, a map 1 m off in its
// true frame (its heading drifted) is scored against the trees those landmarks are, where the
// nearest true landmark is a neighbour.
TEST(SignByOrigins, ScoresAPeersLandmarkAgainstWhatItsRobotMeasured) {
  std::vector<Eigen::Vector2d> truth;
  for (int i = 0; i < 8; ++i) truth.emplace_back(1.5 * i, 0.0);
  LandmarkMap global;
  std::vector<std::vector<LocalLandmark>> origins;
  for (int i = 0; i < 8; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(i);
    l.signature = i < 2 ? i : -1;  // the holder's own two, then robot 2's six
    l.mean = truth[i] + Eigen::Vector2d(1.0, 0.0);
    l.cov = Eigen::Matrix2d::Identity() * 0.25;
    global.landmarks.push_back(l);
    origins.push_back(i < 2 ? std::vector<LocalLandmark>{{1, 1, 10 + i}} : std::vector<LocalLandmark>{{2, 1, 20 + i}});
  }
  // Robot 2's local map: its landmark 20 + i is tree i; landmark 27 is not in it (dropped).
  LocalSignatures known;
  for (int i = 0; i < 7; ++i) known[{2, 1, 20 + i}] = i;
  known[{1, 1, 10}] = 0;
  known[{1, 1, 11}] = 1;
  // By distance: each of robot 2's first five lands on its right-hand neighbour (1 m against
  // 0.5 m), NEES 1 (0.5^2 / 0.25) where its own tree's is 4.
  const MapQuality nearest = EvaluateMap(global, truth, {}, 2.0);
  LandmarkMap signed_map = global;
  const OriginSigning s = SignByOrigins(signed_map, origins, known);
  EXPECT_EQ(s.signed_count, 5);  // 2..6; 7's origin is unknown
  EXPECT_EQ(s.mixed, 0);
  for (int i = 0; i < 7; ++i) EXPECT_EQ(signed_map.landmarks[i].signature, i);
  EXPECT_EQ(signed_map.landmarks[7].signature, -1);
  const MapQuality by_origin = EvaluateMap(signed_map, truth, {}, 2.0);
  EXPECT_EQ(by_origin.matched, 8);
  EXPECT_NEAR(by_origin.rmse_m, 1.0, 1e-12);  // landmark 7 still by distance: its own tree
  EXPECT_NEAR(by_origin.nees_mean, 4.0, 1e-12);
  // By distance, landmark 7 finds its tree taken and stays unmatched: the map looked better.
  EXPECT_EQ(nearest.matched, 7);
  EXPECT_NEAR(nearest.nees_mean, (4.0 + 4.0 + 5 * 1.0) / 7.0, 1e-12);
  // A landmark whose origins name two trees (a false association) counts as mixed: it keeps
  // the holder's signature, and one without stays unsigned (matched by distance).
  origins[0].push_back({2, 1, 23});
  origins[3].insert(origins[3].begin(), LocalLandmark{3, 1, 99});  // unknown: skipped
  origins[3].push_back({2, 1, 24});
  LandmarkMap again = global;
  const OriginSigning t = SignByOrigins(again, origins, known);
  EXPECT_EQ(t.mixed, 2);
  EXPECT_EQ(again.landmarks[0].signature, 0);
  EXPECT_EQ(again.landmarks[3].signature, -1);
  EXPECT_EQ(t.signed_count, 4);
}

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

// Issue J2's coverage of what reached an agent: the share of a reference's signed landmarks the
// map holds; unsigned reference landmarks and repeats count once or not at all.
TEST(CoverageOf, TheShareOfTheReferencesLandmarksTheMapHolds) {
  LandmarkMap reference;
  for (std::int32_t s : {3, 5, 8, 8, 13, -1})
    reference.landmarks.push_back({0, s, {0.0, 0.0}, Eigen::Matrix2d::Identity()});
  EXPECT_DOUBLE_EQ(*CoverageOf(reference, {1, 3, 8}), 0.5);  // 3 and 8 of {3, 5, 8, 13}
  EXPECT_DOUBLE_EQ(*CoverageOf(reference, {3, 5, 8, 13, 20}), 1.0);
  EXPECT_DOUBLE_EQ(*CoverageOf(reference, {}), 0.0);
  EXPECT_FALSE(CoverageOf(LandmarkMap{}, {1, 2}).has_value());
}

}  // namespace
}  // namespace mapmesh
