#pragma once
// What an agent's local estimator does: move with odometry, take scans, give a map and pose.
// Implemented by the filters (LocalSlam) and by the dead-reckoning baseline.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/map/submap_codec.h"
#include "common/slam/motion_model.h"
#include "common/types/choice.h"
#include "common/types/messages.h"

namespace mapmesh {

// The agent's local estimator (agent.slam): the filters of LocalSlam, the compressed EKF in
// submaps joined by least squares (SubmapSlam), or the dead-reckoning baseline.
enum class SlamMethod { kCekf, kEkf, kIekf, kCekfSubmaps, kDeadReckoning };
inline constexpr ChoiceTable<SlamMethod, 5> kSlamMethods{{{SlamMethod::kCekf, "cekf"},
                                                          {SlamMethod::kEkf, "ekf"},
                                                          {SlamMethod::kIekf, "iekf"},
                                                          {SlamMethod::kCekfSubmaps, "cekf_submaps"},
                                                          {SlamMethod::kDeadReckoning, "dead_reckoning"}}};

// What happened to the observations a local mapper was given.
struct MapperStats {
  std::uint64_t offered = 0;         // landmark observations offered
  std::uint64_t associated = 0;      // fused into existing landmarks
  std::uint64_t initialised = 0;     // started a landmark
  std::uint64_t tentative = 0;       // held until a second sighting
  std::uint64_t rejected_gate = 0;   // outliers: failed the innovation gate
  std::uint64_t ambiguous = 0;       // neither compatible nor clearly new: dropped
  std::uint64_t unidentified = 0;    // known association without a signature: dropped
  std::uint64_t out_of_range = 0;    // beyond the configured range limits: dropped
  std::uint64_t invalid = 0;         // NaN, inf or negative range: dropped
  std::uint64_t failed_updates = 0;  // updates refused (innovation covariance not positive definite)
  std::uint64_t diverged = 0;        // cekf_submaps: submaps re-placed by the divergence guard (SubmapOptions)
};

class LocalMapper {
 public:
  virtual ~LocalMapper() = default;
  virtual void Predict(const OdometryControl& u, double dt) = 0;
  virtual void Observe(const std::vector<Observation>& obs, double stamp) = 0;
  virtual LandmarkMap Map() const = 0;
  virtual Pose2 pose() const = 0;
  virtual Eigen::Matrix3d pose_cov() const = 0;
  virtual std::size_t size() const = 0;
  virtual const MapperStats& stats() const = 0;
  // Closed submaps (issue J1): how many this mapper has closed so far, and the i-th (i below
  // that) as it travels under identity id (nullopt when it cannot go on the wire). Mappers
  // without submaps close none.
  virtual std::size_t SubmapsClosed() const { return 0; }
  virtual std::optional<WireSubmap> ClosedSubmap(std::size_t /*i*/, const SubmapId& /*id*/) const {
    return std::nullopt;
  }
  // The submap being mapped, as it would travel under identity id (nullopt when none holds
  // information yet, or for mappers without submaps).
  virtual std::optional<WireSubmap> CurrentSubmap(const SubmapId& /*id*/) const { return std::nullopt; }
};

// True when an observation can be used at all: finite, non-negative range, finite bearing.
inline bool IsValidObservation(const Observation& o) {
  return std::isfinite(o.range) && std::isfinite(o.bearing) && o.range >= 0.0;
}

}  // namespace mapmesh
