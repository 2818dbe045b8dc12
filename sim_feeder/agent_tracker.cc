#include "sim_feeder/agent_tracker.h"

#include <limits>
#include <sstream>

namespace mapmesh {

AgentTracker::AgentTracker(const std::vector<RobotId>& ids) {
  for (RobotId id : ids) agents_[id];
}

void AgentTracker::OnStatus(const AgentStatus& status) {
  auto it = agents_.find(status.robot_id);
  if (it == agents_.end()) return;
  State& s = it->second;
  if (s.stale_incarnation && *s.stale_incarnation == status.incarnation) return;
  if (s.dead && !s.stale_incarnation) return;  // killed, and no restart announced
  if (s.incarnation && *s.incarnation != status.incarnation) {
    // A new process for this robot: its progress starts over.
    s.subscribed = false;
  }
  s.dead = false;
  s.silent = false;  // speaking again
  s.seen = true;
  s.incarnation = status.incarnation;
  s.last = status;
}

void AgentTracker::OnGone(RobotId id, bool process_exists) {
  auto it = agents_.find(id);
  if (it == agents_.end() || !it->second.seen) return;
  State& s = it->second;
  if (process_exists) {
    s.silent = true;
    return;
  }
  s.dead = true;
  s.silent = false;
  s.stale_incarnation = s.incarnation;
  s.seen = false;
}

void AgentTracker::SetProcess(RobotId id, int pid) {
  auto it = agents_.find(id);
  if (it != agents_.end()) it->second.pid = pid;
}

std::optional<int> AgentTracker::process(RobotId id) const {
  auto it = agents_.find(id);
  return it == agents_.end() ? std::nullopt : it->second.pid;
}

void AgentTracker::OnProcessGone(RobotId id) {
  auto it = agents_.find(id);
  if (it == agents_.end()) return;
  it->second.pid.reset();
  if (it->second.silent) OnGone(id, false);
}

bool AgentTracker::IsSilent(RobotId id) const {
  auto it = agents_.find(id);
  return it != agents_.end() && it->second.silent;
}

std::vector<RobotId> AgentTracker::Silent() const {
  std::vector<RobotId> out;
  for (const auto& [id, s] : agents_) {
    if (s.silent) out.push_back(id);
  }
  return out;
}

void AgentTracker::SetSubscribed(RobotId id, bool subscribed) {
  auto it = agents_.find(id);
  if (it != agents_.end()) it->second.subscribed = subscribed;
}

void AgentTracker::MarkDead(RobotId id) {
  auto it = agents_.find(id);
  if (it == agents_.end()) return;
  State& s = it->second;
  s.dead = true;
  s.silent = false;
  s.seen = false;
  s.subscribed = false;
  s.pid.reset();
  if (s.incarnation) s.stale_incarnation = s.incarnation;
}

void AgentTracker::ExpectRestart(RobotId id) {
  auto it = agents_.find(id);
  if (it == agents_.end()) return;
  State& s = it->second;
  if (s.incarnation) s.stale_incarnation = s.incarnation;
  s.dead = false;
  s.silent = false;
  s.seen = false;
  s.subscribed = false;
  s.pid.reset();
}

bool AgentTracker::IsUp(RobotId id) const {
  auto it = agents_.find(id);
  return it != agents_.end() && !it->second.dead && !it->second.silent && it->second.seen && it->second.subscribed;
}

bool AgentTracker::IsDead(RobotId id) const {
  auto it = agents_.find(id);
  return it != agents_.end() && it->second.dead;
}

std::vector<RobotId> AgentTracker::Pending() const {
  std::vector<RobotId> out;
  for (const auto& [id, s] : agents_) {
    if (!s.dead && !(s.seen && s.subscribed)) out.push_back(id);
  }
  return out;
}

std::vector<RobotId> AgentTracker::Lagging(const std::map<RobotId, double>& targets) const {
  std::vector<RobotId> out;
  for (const auto& [id, target] : targets) {
    auto it = agents_.find(id);
    if (it != agents_.end() && (IsUp(id) || it->second.silent) && it->second.last.processed_until + 1e-9 < target) {
      out.push_back(id);
    }
  }
  return out;
}

std::vector<RobotId> AgentTracker::Up() const {
  std::vector<RobotId> out;
  for (const auto& [id, s] : agents_) {
    if (IsUp(id)) out.push_back(id);
  }
  return out;
}

std::vector<AgentStatus> AgentTracker::Statuses() const {
  std::vector<AgentStatus> out;
  for (const auto& [id, s] : agents_) {
    if (s.incarnation) out.push_back(s.last);
  }
  return out;
}

std::optional<ControlCommand> ParseControl(const std::string& line) {
  std::istringstream s(line);
  std::string word;
  if (!(s >> word)) return std::nullopt;
  if (word == "continue") return ControlCommand{ControlCommand::Kind::kContinue};
  if (word == "stop") return ControlCommand{ControlCommand::Kind::kStop};
  long id = 0;
  if (!(s >> id) || id <= 0) return std::nullopt;
  if (word == "dead") return ControlCommand{ControlCommand::Kind::kDead, static_cast<RobotId>(id)};
  if (word == "expect") return ControlCommand{ControlCommand::Kind::kExpect, static_cast<RobotId>(id)};
  long pid = 0;
  if (word == "pid" && (s >> pid) && pid > 0 && pid <= std::numeric_limits<int>::max()) {
    return ControlCommand{ControlCommand::Kind::kPid, static_cast<RobotId>(id), static_cast<int>(pid)};
  }
  return std::nullopt;
}

}  // namespace mapmesh
