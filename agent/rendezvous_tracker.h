#pragma once
// RendezvousTracker: what an agent does with robots it sees and robots that see it (thesis
// 3.3.1; pure, time is the scenario time the agent has processed). It publishes each sighting
// of a peer with its own pose estimate then (at most one per peer every period_s), answers a
// peer's sighting of it with its own pose estimate at that stamp, and turns each sighting and
// answer into a correspondence between the two map frames (rendezvous.h: SightingPair): one
// point of the sighted robot in both. Two robots that saw each other within mutual_within_s
// also give a whole transform (RendezvousAlign). Per peer frame (robot and incarnation) it
// keeps the newest correspondences and fits the transform they agree on (FitRendezvous)
// whenever new ones arrived; MapExchange verifies a fit against the maps before using it.

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <map>
#include <vector>

#include "agent/peer_state.h"
#include "common/geometry/pose2.h"
#include "common/merge/rendezvous.h"
#include "common/options/rendezvous_options.h"
#include "common/types/messages.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {

struct RendezvousStats {
  std::uint32_t sightings_sent = 0;  // own sightings of peers published
  std::uint32_t answers_sent = 0;    // own poses sent in answer to a peer's sighting
  std::uint32_t sightings_used = 0;  // peers' sightings of us made correspondences
  std::uint32_t answers_used = 0;    // peers' answers to our sightings made correspondences
  std::uint32_t mutual = 0;          // mutual rendezvous found
  std::uint32_t refused = 0;         // malformed messages (non-finite, bad covariance or sigmas)
  std::uint32_t unmatched = 0;       // answers to no sighting of ours; sightings of us outside our pose history
  std::uint32_t fits = 0, fits_accepted = 0;
};

class RendezvousTracker {
 public:
  RendezvousTracker(RobotId self, std::uint32_t incarnation, std::vector<RobotId> robots,
                    const RendezvousOptions& options, double sigma_range_m, double sigma_bearing_rad);

  // The own pose estimate at a processed stamp (after each scan and each odometry interval).
  void OnPose(double stamp, const Pose2& pose, const Eigen::Matrix3d& cov);
  // The robots in an own scan at `stamp`, seen from `pose`: the sightings to publish.
  std::vector<Sighting> OnScan(const std::vector<Observation>& obs, double stamp, const Pose2& pose,
                               const Eigen::Matrix3d& cov);
  // A peer's message (it passed the radio gate). Malformed ones are counted and dropped.
  void OnMessage(const Sighting& m);
  // After processing up to `now`: peers' sightings of us at stamps reached so far become
  // correspondences, and their answers are returned for publishing.
  std::vector<Sighting> Advance(double now);
  // Fits for the peer frames that received correspondences since the last call.
  std::vector<std::pair<PeerKey, RendezvousFit>> TakeFits();

  const RendezvousStats& stats() const { return stats_; }

 private:
  struct PoseAt {
    double t;
    Pose2 pose;
    Eigen::Matrix3d cov;
  };
  struct OwnSighting {
    double t;
    RobotId peer;
    double range, bearing;
    Pose2 pose;
    Eigen::Matrix3d cov;
  };
  struct Frame {
    std::deque<SightingPair> pairs;
    std::deque<RendezvousResult> mutual;
    double updated = 0.0;
    bool fresh = false;
  };
  bool InRun(RobotId r) const;
  bool PoseAtStamp(double t, PoseAt* out) const;
  Frame& FrameOf(const PeerKey& key, double now);
  void AddPair(const PeerKey& key, const SightingPair& p);
  void Forget(double now);

  RobotId self_;
  std::uint32_t incarnation_;
  std::vector<RobotId> robots_;
  RendezvousOptions options_;
  double sigma_range_, sigma_bearing_;
  std::deque<PoseAt> poses_;
  std::deque<OwnSighting> own_;
  std::map<RobotId, double> last_sent_;
  std::deque<Sighting> pending_;  // peers' sightings of us, waiting for our pose at their stamp
  std::map<PeerKey, Frame> frames_;
  double now_ = 0.0;
  RendezvousStats stats_;
};

// Whether a message can be used: finite, a symmetric positive-definite pose covariance, and for a
// sighting a non-negative range and positive sigmas.
bool SightingWellFormed(const Sighting& m);

}  // namespace mapmesh
