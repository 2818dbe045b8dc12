#include "agent/robot_writers.h"

namespace mapmesh {

bool RobotWriters::Admits(RobotId robot, std::uint32_t incarnation, const std::string& writer) const {
  if (writer.empty()) return true;
  const std::string* bound = Bound(robot, incarnation);
  return !bound || *bound == writer;
}

void RobotWriters::Bind(RobotId robot, std::uint32_t incarnation, const std::string& writer) {
  if (writer.empty() || !writers_.try_emplace({robot, incarnation}, writer).second) return;
  std::deque<std::uint32_t>& order = order_[robot];
  order.push_back(incarnation);
  while (order.size() > kIncarnationsPerRobot) {
    writers_.erase({robot, order.front()});
    order.pop_front();
  }
}

const std::string* RobotWriters::Bound(RobotId robot, std::uint32_t incarnation) const {
  const auto it = writers_.find({robot, incarnation});
  return it == writers_.end() ? nullptr : &it->second;
}

}  // namespace mapmesh
