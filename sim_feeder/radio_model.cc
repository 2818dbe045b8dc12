#include "sim_feeder/radio_model.h"

#include <algorithm>

namespace mapmesh {

std::vector<Link> LinksInRange(const std::vector<RobotPosition>& robots, double range_m) {
  std::vector<Link> links;
  if (range_m <= 0.0) return links;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    for (std::size_t j = i + 1; j < robots.size(); ++j) {
      const double dx = robots[i].x - robots[j].x, dy = robots[i].y - robots[j].y;
      if (dx * dx + dy * dy <= range_m * range_m) {
        links.push_back({std::min(robots[i].id, robots[j].id), std::max(robots[i].id, robots[j].id)});
      }
    }
  }
  std::sort(links.begin(), links.end(),
            [](const Link& a, const Link& b) { return a.a != b.a ? a.a < b.a : a.b < b.b; });
  return links;
}

}  // namespace mapmesh
