#pragma once
// Data association (thesis 3.1): which landmark each observation of a scan comes from.
// - known: by the signature the sensor reports (MRCLAM barcodes, simulated identities);
// - ICNN: individual compatibility, nearest neighbour by Mahalanobis distance (eq. 1-4);
// - JCBB: joint compatibility branch and bound (Neira & Tardos 2001; eq. 5-8), which keeps
//   the largest set of pairings that is compatible as a whole.
// Every method gates with the innovation's chi-square test, so spurious readings (outliers)
// are rejected rather than fused. An observation compatible with nothing and far from every
// landmark starts a new one; one in between is discarded as ambiguous.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/slam/landmark_filter.h"
#include "common/types/choice.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

// kAuto is a setting, not a method: known when the sensor reports signatures, else JCBB
// (Resolve); Associate takes the others.
enum class AssociationMethod { kAuto, kKnown, kIcnn, kJcbb };
inline constexpr ChoiceTable<AssociationMethod, 4> kAssociationMethods{{{AssociationMethod::kAuto, "auto"},
                                                                        {AssociationMethod::kKnown, "known"},
                                                                        {AssociationMethod::kIcnn, "icnn"},
                                                                        {AssociationMethod::kJcbb, "jcbb"}}};

struct AssociationOptions {
  AssociationMethod method = AssociationMethod::kAuto;  // agent.association
  double gate_probability = 0.99;    // agent.gate_probability: individual and joint compatibility, chi-square quantile
  double new_landmark_chi2 = 13.82;  // agent.new_landmark_chi2: farther than this (2 dof, 99.9 %) from every
                                     // candidate: new
  long max_jcbb_nodes = 200000;      // JCBB keeps the best hypothesis found within this many nodes

  // The method for a sensor that does (or does not) report signatures: kAuto resolved.
  AssociationMethod Resolve(bool signatures) const {
    if (method != AssociationMethod::kAuto) return method;
    return signatures ? AssociationMethod::kKnown : AssociationMethod::kJcbb;
  }

  // Reads its keys of the scenario's agent section (docs/SCENARIOS.md).
  template <typename Reader>
  void Read(Reader& r) {
    r.GetChoice("association", method, kAssociationMethods);
    r.GetInRange("gate_probability", gate_probability, 0.5, 0.999999);
    r.GetPositiveUpTo("new_landmark_chi2", new_landmark_chi2, limits::kMaxChi2);
  }
};

// The map around the robot and the scan, as the filter sees them.
struct AssociationProblem {
  Pose2 robot;
  std::vector<LandmarkId> candidates;
  std::vector<Eigen::Vector2d> means;  // per candidate
  Eigen::MatrixXd joint_cov;           // of [robot; candidates], 3 + 2K square
  Eigen::Matrix2d obs_cov = Eigen::Matrix2d::Identity();
  std::vector<Eigen::Vector2d> z;        // observations [range, bearing]
  std::vector<std::int32_t> signatures;  // per observation, -1 when unknown
};

struct AssociationResult {
  static constexpr int kNew = -1;
  static constexpr int kDiscard = -2;
  std::vector<int> match;    // per observation: a candidate index, kNew or kDiscard
  int rejected_by_gate = 0;  // known pairings whose innovation failed the gate (outliers)
  int ambiguous = 0;         // compatible with nothing, yet too close to a landmark to be new
  int unidentified = 0;      // known mode: observations without a signature
  long jcbb_nodes = 0;
};

// Builds the problem for a filter and a scan (candidates: the filter's).
AssociationProblem MakeAssociationProblem(const LandmarkFilter& filter, const Eigen::Matrix2d& obs_cov,
                                          const std::vector<Eigen::Vector2d>& z,
                                          const std::vector<std::int32_t>& signatures);

AssociationResult Associate(const AssociationProblem& problem, const AssociationOptions& options);

// Squared Mahalanobis distance of observation i to candidate j, and its innovation.
double MahalanobisSquared(const AssociationProblem& problem, int i, int j, Eigen::Vector2d* innovation = nullptr);

}  // namespace mapmesh
