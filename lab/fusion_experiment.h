#pragma once
// Fusion experiments (thesis 5.2-5.4): two robots' local maps from one SLAM run are aligned
// (map overlap, unknown start poses), robot 2's map is fused into robot 1's cloned global
// map by each estimator, and everything is scored on the overlap (the global landmarks both
// robots contributed to) against the truth: the merged estimate in robot 1's frame, and each
// robot's own estimate of the same landmarks in its own frame.

#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "common/merge/fusion.h"
#include "common/merge/map_alignment.h"
#include "common/metrics/landmark_metrics.h"
#include "lab/slam_experiment.h"

namespace mapmesh::lab {

struct FusionTrialOptions {
  RobotId a = 1, b = 2;           // b's map is fused into a's global map
  bool oracle_alignment = false;  // use the true transform (zero covariance) instead of aligning
  AlignmentOptions align;
  std::vector<FusionMethod> methods{FusionMethod::kMaximumLikelihood,
                                    FusionMethod::kInformation,
                                    FusionMethod::kCiConstant,
                                    FusionMethod::kCiDeterminant,
                                    FusionMethod::kCiTrace,
                                    FusionMethod::kOgk,
                                    FusionMethod::kCiOgk};
  bool keep_estimates = false;  // keep every overlap landmark's estimates (FusionTrialResult::estimates)
};

// One estimate of an overlap landmark in robot a's frame (Fig. 58): robot a's own, robot b's
// placed by the alignment (its covariance included), or an estimator's merged one.
struct OverlapEstimate {
  std::string source;  // "robot_a", "robot_b" or the estimator (ToString(FusionMethod))
  int signature = -1;  // the landmark's true identity
  Eigen::Vector2d truth = Eigen::Vector2d::Zero();
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
};

// Means over the overlap landmarks of one map.
struct OverlapScore {
  int landmarks = 0;
  double nees = 0.0;              // mean NEES (infinite when a covariance is singular)
  double consistent_ratio = 0.0;  // NEES below 5.99
  double det = 0.0;               // mean determinant of the covariances (m^4)
  double area_m2 = 0.0;           // mean covariance-ellipse area pi sqrt(det) (thesis eq. 97, 1 sigma)
  double rmse_m = 0.0;
};

struct MethodScore {
  FusionMethod method = FusionMethod::kCiConstant;
  OverlapScore merged;
  double global_nees = 0.0, global_consistent_ratio = 0.0, global_rmse_m = 0.0;  // whole global map
  int global_landmarks = 0;
};

struct FusionTrialResult {
  std::uint64_t seed = 0;
  double value = 0.0;  // the swept parameter
  RobotId robot_a = 0, robot_b = 0;
  AlignmentVerdict verdict = AlignmentVerdict::kTooFewLandmarks;
  // The thesis's alignment figures (Figs. 67, 71, 75, 77, 80), not with an oracle alignment:
  double similarity_true_ratio = 0.0;         // "map similarity": share of the triangle-matching candidates that are
                                              // true pairs (0 when there are none), with the options' matcher ...
  double thesis_similarity_true_ratio = 0.0;  // ... and with the thesis's similarity metric (eq. 51-53)
  double ransac_true_recall = 0.0;            // "RANSAC success": share of the true pairs (landmarks both maps hold)
                                              // among the alignment's inliers
  bool correct = false;                       // accepted, within 1 m at b's centroid and 2 deg of the truth
  bool fused = false;                         // aligned (or oracle) and scored
  double translation_error_m = 0.0, rotation_error_deg = 0.0;
  AssociationScore association;  // of the overlap, against the truth
  OverlapScore a, b;             // each robot's own estimates of the overlap landmarks
  std::vector<MethodScore> methods;
  std::vector<OverlapEstimate> estimates;  // with keep_estimates, by landmark: robot a, robot b, each method
};

// Scores one run (needs the true frame origins and landmark truth, as simulations give).
FusionTrialResult RunFusionTrial(const std::vector<SlamRunResult>& robots, const FusionTrialOptions& options,
                                 std::mt19937_64& rng);

// CSV of a trial's estimates: source, signature, truth, mean and covariance (cxx, cxy, cyy).
std::string OverlapEstimatesCsv(const std::vector<OverlapEstimate>& estimates);

// A scenario for (swept value, seed).
using ScenarioMaker = std::function<Scenario(double value, std::uint64_t seed)>;

struct FusionSweepOptions {
  std::vector<double> values;
  int seeds = 100;
  std::uint64_t first_seed = 1;
  int threads = 0;  // 0: the machine's cores
  FusionTrialOptions trial;
  // Robot pairs (a, b) scored in every run (b fused into a); empty: only trial.a and trial.b.
  std::vector<std::pair<RobotId, RobotId>> pairs;
  SlamRunOptions slam;
  std::function<void(int done, int total)> progress;
};

// Every (value, seed) run, in order of value then seed (then pair).
std::vector<FusionTrialResult> RunFusionSweep(const ScenarioMaker& make, const FusionSweepOptions& options);

// One row per (value, method), averaged over the runs that fused: run figures (alignment,
// association) by run, landmark figures over the overlap landmarks of all runs.
struct FusionSweepRow {
  double value = 0.0;
  RobotId robot_a = 0, robot_b = 0;
  FusionMethod method = FusionMethod::kCiConstant;
  int runs = 0, fused_runs = 0;
  double translation_error_m = 0.0, rotation_error_deg = 0.0;
  double association_precision = 0.0, association_recall = 0.0;
  double similarity_true_ratio = 0.0, ransac_true_recall = 0.0;  // means over all runs (oracle: 0)
  double thesis_similarity_true_ratio = 0.0;
  int correct_runs = 0;
  double overlap_landmarks = 0.0;  // per fused run
  OverlapScore a, b, merged;       // landmarks: the total over the runs
  double global_nees = 0.0, global_consistent_ratio = 0.0;
};
std::vector<FusionSweepRow> SummariseFusionSweep(const std::vector<FusionTrialResult>& trials,
                                                 const std::vector<FusionMethod>& methods);
std::string FusionSweepCsv(const std::string& parameter, const std::vector<FusionSweepRow>& rows);

// Thesis Table 7 on real data: the Victoria Park replay split into K robots, every pair of
// robots aligned and fused (b into a), scored against a reference map (the whole run as one
// robot, aligned to each map), with the reference's covariance added to each NEES: there is
// no landmark ground truth in Victoria Park.
struct VictoriaPairResult {
  RobotId a = 0, b = 0;
  AlignmentVerdict verdict = AlignmentVerdict::kTooFewLandmarks;
  int overlap = 0;
  double nees_a = 0.0, nees_b = 0.0;
  std::vector<std::pair<FusionMethod, double>> merged_nees;
};
std::vector<VictoriaPairResult> RunVictoriaPairs(const std::vector<SlamRunResult>& robots, const LandmarkMap& reference,
                                                 const FusionTrialOptions& options, std::mt19937_64& rng);
std::string VictoriaPairsCsv(const std::vector<VictoriaPairResult>& pairs);

}  // namespace mapmesh::lab
