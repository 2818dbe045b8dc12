#pragma once
// What the feeder publishes, one instant at a time: a simulation or a dataset replay.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/types/messages.h"

namespace mapmesh {

// Everything stamped at one instant, in publication order.
struct FeedBatch {
  double stamp = 0.0;
  std::vector<Scan> scans;
  std::vector<Odometry> odom;
  std::vector<GroundTruth> truth;
  std::optional<RadioLinks> links;
};

// The ground truth an evaluation needs besides the trajectories.
struct WorldTruth {
  std::vector<Eigen::Vector2d> landmarks;         // index = signature
  std::vector<std::pair<RobotId, Pose2>> starts;  // robots whose true start pose is known
  std::vector<bool> seen;                         // per landmark: observed by some robot so far
  bool headings_known = true;                     // false: truth trajectories are positions only
};

class FeedSource {
 public:
  virtual ~FeedSource() = default;
  // True when no batch is left.
  virtual bool Done() const = 0;
  // The next batch; stamps increase strictly.
  virtual FeedBatch Next() = 0;
  virtual const WorldTruth& Truth() const = 0;
};

}  // namespace mapmesh
