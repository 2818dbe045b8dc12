#pragma once
// Frame alignment from a rendezvous (thesis 3.3.1, eq. 39-50; left as future work there):
// two robots range and bear to each other at about the same time. The two ranges are fused by
// their inverse variances (eq. 40), the relative heading follows from the two bearings
// (eq. 44: pi + bearing_12 - bearing_21), and with each robot's pose in its own map frame the
// transform between the map frames follows (eq. 45-50), with a covariance propagated from
// both poses and the four measurements.

#include <Eigen/Core>
#include <optional>
#include <span>
#include <string_view>

#include "common/geometry/pose2.h"

namespace mapmesh {

struct RendezvousInput {
  Pose2 pose1;  // robot 1 in map frame 1
  Eigen::Matrix3d cov1 = Eigen::Matrix3d::Zero();
  Pose2 pose2;  // robot 2 in map frame 2
  Eigen::Matrix3d cov2 = Eigen::Matrix3d::Zero();
  double range12 = 0.0, bearing12 = 0.0;  // robot 1's sighting of robot 2
  double range21 = 0.0, bearing21 = 0.0;  // robot 2's sighting of robot 1
  double sigma_range1 = 0.1, sigma_bearing1 = 0.02;
  double sigma_range2 = 0.1, sigma_bearing2 = 0.02;
};

struct RendezvousResult {
  Pose2 transform;  // maps frame 2 into frame 1
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double range = 0.0;               // the fused range (eq. 40)
  double range_disagreement = 0.0;  // |range12 - range21| in sigmas of their difference
};

// nullopt for non-finite input or non-positive range sigmas.
std::optional<RendezvousResult> RendezvousAlign(const RendezvousInput& in);

// Squared Mahalanobis distance between two estimates of one transform (x, y, theta; the angle
// difference wrapped) under the sum of their covariances; infinity when that is not positive
// definite.
double TransformDistance2(const Pose2& a, const Eigen::Matrix3d& cov_a, const Pose2& b, const Eigen::Matrix3d& cov_b);

// A point estimate with its covariance.
struct PointEstimate {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
};

// Where a robot sighted at (range, bearing) from `observer` (with covariance observer_cov, in
// the observer's map frame) stands in that frame: the observer's position plus the rotated
// range-bearing vector, with the covariance of both propagated (thesis eq. 42-43 for one
// sighting). nullopt for non-finite input or non-positive sigmas.
std::optional<PointEstimate> SightedPosition(const Pose2& observer, const Eigen::Matrix3d& observer_cov, double range,
                                             double bearing, double sigma_range, double sigma_bearing);

// One sighting between two robots, made a correspondence between two map frames: the sighted
// robot's position in the own frame (where the observer placed it, or where the own robot was
// when a peer saw it) and in the peer's frame (where its own estimate put it then, or where
// the peer observer placed it). A single sighting fixes the translation for a given rotation;
// two or more taken apart (or one mutual rendezvous) fix the whole transform.
struct SightingPair {
  double stamp = 0.0;
  PointEstimate own, peer;
};

struct RendezvousFitOptions {
  int min_sightings = 3;                // inlier sightings needed (a mutual rendezvous is two)
  double min_baseline_m = 1.0;          // inlier sightings this far apart in the peer's frame fix the rotation
                                        // (a mutual rendezvous fixes it by itself)
  double gate_probability = 0.99;       // a sighting agrees with a transform inside this chi-square gate
  double min_inlier_share = 0.5;        // at least this share of the sightings must agree
  double residual_probability = 0.999;  // chi-square test on the inliers' residuals ...
  double residual_tolerance = 1.5;      // ... with its bound scaled by this (as for map alignment)
};

enum class RendezvousVerdict {
  kAccepted = 0,
  kTooFewSightings,    // fewer sightings than min_sightings
  kNoBaseline,         // the sightings do not fix the rotation: too close together, no mutual one
  kTooFewInliers,      // the best transform agrees with too few of them, or too small a share
  kResidualsTooLarge,  // the inliers do not fit it as their covariances say
  kDegenerate,         // singular information
};
std::string_view ToString(RendezvousVerdict v);

struct RendezvousFit {
  RendezvousVerdict verdict = RendezvousVerdict::kTooFewSightings;
  bool accepted() const { return verdict == RendezvousVerdict::kAccepted; }
  Pose2 transform;                                // maps the peer's frame into the own frame
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();  // of (x, y, theta)
  int pairs = 0, mutual = 0;                      // valid inputs
  int inlier_pairs = 0, inlier_mutual = 0;
  double residual_chi2 = 0.0, residual_bound = 0.0;
};

// The transform from the peer's frame into the own frame that the sightings agree on:
// hypotheses from every mutual rendezvous and every two sightings at least min_baseline_m
// apart, the one most sightings agree with (within the chi-square gate on their combined
// covariance; RANSAC-like, exhaustive over the few sightings given), refined by weighted least
// squares on its inliers, then tested like a map alignment (count, share, residuals).
// Sightings of one pair of robots share both robots' pose errors, so the covariance combines
// the inliers by Covariance Intersection with equal weights (the information of one average
// sighting set, as for map alignment's LandmarkErrors::kUnknownCorrelation).
RendezvousFit FitRendezvous(std::span<const SightingPair> pairs, std::span<const RendezvousResult> mutual,
                            const RendezvousFitOptions& options);

}  // namespace mapmesh
