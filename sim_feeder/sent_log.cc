#include "sim_feeder/sent_log.h"

namespace mapmesh {

void SentLog::Processed(RobotId id, double processed_until) {
  auto it = log_.find(id);
  if (it == log_.end()) return;
  // Publication order is time order per robot but for the held-back odometry of lockstep, which
  // goes out after the scans of its interval: drop what is processed wherever it is.
  std::erase_if(it->second, [&](const Entry& e) { return e.stamp <= processed_until + 1e-9; });
}

std::vector<SentLog::Message> SentLog::Unprocessed(RobotId id) const {
  std::vector<Message> out;
  if (auto it = log_.find(id); it != log_.end()) {
    for (const Entry& e : it->second) out.push_back(e.message);
  }
  return out;
}

const std::vector<SentLog::Message>& StreamLog::Of(RobotId id) const {
  static const std::vector<SentLog::Message> kNone;
  auto it = log_.find(id);
  return it == log_.end() ? kNone : it->second;
}

std::size_t SentLog::size(RobotId id) const {
  auto it = log_.find(id);
  return it == log_.end() ? 0 : it->second.size();
}

}  // namespace mapmesh
