#pragma once
// What the feeder knows about each agent of the run, for lockstep pacing: whether it is
// up and subscribed, silent, dead, or restarting, and how far it has processed. Pure: the DDS
// facts (status samples, matched-reader counts), the state of the agent's process and
// launcher commands come in as calls.
//
// Liveliness loss is not death while the process exists: an agent whose writers went quiet
// but whose process is still there (stopped with SIGSTOP, or starved) is *silent*. It is
// still waited for at every barrier, and up again with its next status. Only a process that
// is gone (or, when the feeder does not know the process, lost liveliness) is dead.

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/types/messages.h"

namespace mapmesh {

class AgentTracker {
 public:
  explicit AgentTracker(const std::vector<RobotId>& ids);

  // A status sample from an agent process.
  void OnStatus(const AgentStatus& status);
  // The agent's status writer went away (DDS liveliness lost or instance disposed), while its
  // process still exists (then it is silent) or not (dead).
  void OnGone(RobotId id, bool process_exists = false);
  // The process of the agent's current incarnation (from the launcher), and its end.
  void SetProcess(RobotId id, int pid);
  std::optional<int> process(RobotId id) const;
  void OnProcessGone(RobotId id);
  // subscribed: every sensor writer of this robot has matched a reader since the last
  // restart (the caller compares cumulative match counts).
  void SetSubscribed(RobotId id, bool subscribed);
  // The launcher killed the agent: stop waiting for it.
  void MarkDead(RobotId id);
  // The launcher restarted the agent: wait for a new incarnation to come up.
  void ExpectRestart(RobotId id);

  // Up: a status from the current incarnation has arrived and the sensor topics are matched.
  bool IsUp(RobotId id) const;
  bool IsDead(RobotId id) const;
  bool IsSilent(RobotId id) const;
  // Agents that are silent (see above).
  std::vector<RobotId> Silent() const;
  // Agents neither up nor dead (starting or restarting).
  std::vector<RobotId> Pending() const;
  // Up or silent agents whose processed_until is below their target (agents without a target
  // are not waited for).
  std::vector<RobotId> Lagging(const std::map<RobotId, double>& targets) const;
  std::vector<RobotId> Up() const;
  // The latest status of each agent that has sent one.
  std::vector<AgentStatus> Statuses() const;

 private:
  struct State {
    bool seen = false;  // a status of the current incarnation arrived
    bool subscribed = false;
    bool dead = false;
    bool silent = false;  // liveliness lost, process still there
    std::optional<int> pid;
    std::optional<std::uint32_t> incarnation;
    std::optional<std::uint32_t> stale_incarnation;  // killed process: ignore its statuses
    AgentStatus last;
  };
  std::map<RobotId, State> agents_;
};

// A launcher command read from the feeder's stdin: "dead ID", "expect ID", "pid ID PID" (the
// process of the agent's current incarnation), "continue", "stop". Returns nullopt for
// anything else.
struct ControlCommand {
  enum class Kind { kDead, kExpect, kPid, kContinue, kStop } kind;
  RobotId id = 0;
  int pid = 0;
};
std::optional<ControlCommand> ParseControl(const std::string& line);

}  // namespace mapmesh
