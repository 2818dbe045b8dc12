#pragma once
// What the lockstep feeder published to each agent that the agent has not yet reported
// processed, so that it can be sent again when the agent's readers are matched anew: a paused
// (SIGSTOPped) agent's DDS participant lapses after its lease, and the samples that were in
// flight to it then are gone; when it resumes, the feeder re-publishes them in order. Pure.

#include <cstdint>
#include <deque>
#include <map>
#include <variant>
#include <vector>

#include "common/types/messages.h"

namespace mapmesh {

class SentLog {
 public:
  using Message = std::variant<Odometry, Scan>;

  // Remembers a message published to its robot.
  void Record(const Odometry& o) { Push(o.robot_id, o.stamp, o); }
  void Record(const Scan& s) { Push(s.robot_id, s.stamp, s); }
  // The agent reports every stamp up to processed_until applied: forgets those messages.
  void Processed(RobotId id, double processed_until);
  // What the agent has not reported processed, in publication order.
  std::vector<Message> Unprocessed(RobotId id) const;
  // The agent is gone (killed, or restarting with a new incarnation): forgets it.
  void Forget(RobotId id) { log_.erase(id); }
  std::size_t size(RobotId id) const;

 private:
  struct Entry {
    double stamp;
    Message message;
  };
  void Push(RobotId id, double stamp, Message m) { log_[id].push_back({stamp, std::move(m)}); }
  std::map<RobotId, std::deque<Entry>> log_;
};

// Everything published to each robot, in publication order, for the whole run: the robot's
// driver log. A restarted agent is sent its robot's stream again from the start, so that it
// rebuilds its map in its own frame (LockstepPacer). Pure.
class StreamLog {
 public:
  void Record(const Odometry& o) { log_[o.robot_id].emplace_back(o); }
  void Record(const Scan& s) { log_[s.robot_id].emplace_back(s); }
  const std::vector<SentLog::Message>& Of(RobotId id) const;
  std::size_t size(RobotId id) const { return Of(id).size(); }

 private:
  std::map<RobotId, std::vector<SentLog::Message>> log_;
};

}  // namespace mapmesh
