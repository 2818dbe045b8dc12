#pragma once
// Radio links from true distances: two robots can hear each other within range_m.

#include <vector>

#include "common/geometry/pose2.h"
#include "common/types/messages.h"

namespace mapmesh {

struct RobotPosition {
  RobotId id = 0;
  double x = 0.0, y = 0.0;
};

// Every unordered pair (a < b) no further apart than range_m, sorted.
std::vector<Link> LinksInRange(const std::vector<RobotPosition>& robots, double range_m);

}  // namespace mapmesh
