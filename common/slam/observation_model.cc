#include "common/slam/observation_model.h"

#include <cmath>

namespace mapmesh {

Eigen::Vector2d ObserveRangeBearing(const Pose2& robot, const Eigen::Vector2d& landmark, Matrix23* h_robot,
                                    Eigen::Matrix2d* h_landmark) {
  const double dx = landmark.x() - robot.x, dy = landmark.y() - robot.y;
  const double q = dx * dx + dy * dy, r = std::sqrt(q);
  if (h_robot) {
    *h_robot << -dx / r, -dy / r, 0.0,  //
        dy / q, -dx / q, -1.0;
  }
  if (h_landmark) {
    *h_landmark << dx / r, dy / r,  //
        -dy / q, dx / q;
  }
  return {r, WrapAngle(std::atan2(dy, dx) - robot.theta)};
}

Eigen::Vector2d InverseRangeBearing(const Pose2& robot, const Eigen::Vector2d& z, Matrix23* g_robot,
                                    Eigen::Matrix2d* g_z) {
  const double a = robot.theta + z.y();
  const double c = std::cos(a), s = std::sin(a), r = z.x();
  if (g_robot) {
    *g_robot << 1.0, 0.0, -r * s,  //
        0.0, 1.0, r * c;
  }
  if (g_z) {
    *g_z << c, -r * s,  //
        s, r * c;
  }
  return {robot.x + r * c, robot.y + r * s};
}

}  // namespace mapmesh
