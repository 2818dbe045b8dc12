#pragma once
// How the feeder paces the stream against the agents, pure: the lockstep protocol without its
// DDS, clock, /proc and stdin. The feeder's main loop feeds it facts (status samples, lost
// writers, matched-reader counts, launcher commands) and asks it what to publish and when to
// go on; wall time comes in as an argument (seconds, any origin), and the state of an agent's
// process through a probe.
//
// The protocol. Time is cut into windows of feeder.lockstep_window_s (and at hold points and
// the end). Each robot's latest odometry is held back until it is known whether the window
// closes before that robot's next one: the held message then carries the sync flag, and the
// barrier waits until every up (or silent) agent reports processed_until at least the last
// odometry stamp published to it. An agent that makes no progress for stall_timeout_s wall
// seconds is given up (unless its process is stopped: then it is paused, and waited for).
// Messages published in lockstep are kept until the agent reports them processed, so that an
// agent whose readers match anew without a restart (its participant lapsed while paused) gets
// them again. With keep_streams, in either pace, everything published to a robot is kept for
// the run, and a restarted agent is sent its robot's whole stream again once its readers match,
// before anything new (a restart happens at a hold point, and the feeder goes on only once the
// agent is up and the replay done): it rebuilds its map from the start, in its own frame. The
// replay goes in pieces of at most replay_span_s of scenario time, each once the agent has
// processed the last: sensor topics are not ordered against each other, and a burst would put
// scans further ahead of the odometry taken than an agent finds plausible. In real time there is no hold-back and no waiting; windows still mark when the
// feeder reports progress and stops at hold points.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <vector>

#include "common/types/messages.h"
#include "sim_feeder/agent_tracker.h"
#include "sim_feeder/sent_log.h"

namespace mapmesh {

// The state of a process on this host: gone (or a zombie), stopped (SIGSTOP, traced), or
// anything else.
enum class ProcessState { kGone, kStopped, kRunning };
using ProcessProbe = std::function<ProcessState(int pid)>;

class LockstepPacer {
 public:
  struct Options {
    bool lockstep = true;            // feeder.pace: wait at barriers and keep what was sent
    double window_s = 1.0;           // feeder.lockstep_window_s
    double stall_timeout_s = 120.0;  // wall seconds without progress before an agent is given up
    std::vector<double> holds;       // scenario times to stop at until the launcher continues
    double exchange_period_s = 0.0;  // lockstep: agent.map_publish_period_s, the exchange points (0: none)
    bool keep_streams = true;        // feeder.keep_streams: replay a robot's stream to a restarted agent
    double replay_span_s = 10.0;     // scenario seconds of stream per replay piece (see above)
  };
  LockstepPacer(const std::vector<RobotId>& ids, Options options, ProcessProbe probe);

  // --- What the agents and the launcher say.
  // A status sample. Returns true when the agent was silent and now speaks again.
  bool OnStatus(const AgentStatus& status);
  // The agent's status writer went away. Returns nullopt when that changes nothing (the agent
  // is already dead or silent), else whether its process still exists (then it is silent and
  // still waited for; otherwise dead).
  std::optional<bool> OnStatusGone(RobotId id);
  // Silent agents whose process has ended since: now dead, and what was sent them forgotten.
  std::vector<RobotId> ReapSilent();
  // The cumulative number of readers matched by both sensor writers of the robot. Returns the
  // messages to send again: those the agent has not processed, when its readers matched anew
  // without a restart; else nothing. (A restarted agent's first match starts its replay.)
  std::vector<SentLog::Message> OnMatches(RobotId id, std::uint32_t total_matches);
  // A launcher command other than stop (the caller handles stop). For "expect", the robot's
  // current cumulative match count is the base its next subscription is counted from.
  void OnControl(const ControlCommand& command, std::uint32_t total_matches);

  // The next piece of a restarted agent's replay, when one is due: the first once its readers
  // matched, each next once it reported the last processed. Empty otherwise.
  std::vector<SentLog::Message> ReplayDue(RobotId id);
  bool Replaying(RobotId id) const { return replays_.count(id) > 0; }

  // --- The stream, batch by batch.
  // An odometry message of the current batch: what to publish now (in lockstep, the robot's
  // previously held message, if any; in real time, this one).
  std::optional<Odometry> Admit(const Odometry& o);
  // Whether the batch at `stamp` closes a window (a window boundary, a hold point, the last).
  bool IsBarrier(double stamp, bool last) const;
  // Closes the window at `stamp`: the held odometry, each flagged sync, to publish now.
  std::vector<Odometry> CloseWindow(double stamp);
  // A sensor message was published (in lockstep it is kept until processed).
  void Published(const Odometry& o);
  void Published(const Scan& s);
  // Removes the hold points at or before `stamp` and returns how many there were.
  int TakeHolds(double stamp);

  // --- Waiting. Begin, then poll with the wall time until the poll says it is over.
  // Startup (or a restart): until no agent is pending (a restarted one: until its replay is
  // done). The poll returns nullopt while waiting, then the agents that did not come up within
  // timeout_s (empty when all did).
  void BeginStartup(double wall_now, double timeout_s);
  std::optional<std::vector<RobotId>> PollStartup(double wall_now) const;
  // A hold point: until the launcher says continue.
  void BeginHold() { continue_ = false; }
  bool HoldReleased() const { return continue_; }
  // The lockstep barrier: until every up or silent agent has processed what was published to
  // it. Stalled agents are marked dead.
  void BeginBarrier(double wall_now);
  struct BarrierPoll {
    bool done = false;
    std::vector<RobotId> stalled;  // given up at this poll (then done)
    std::vector<RobotId> waiting;  // not done: the agents that have not processed what was sent them
  };
  BarrierPoll PollBarrier(double wall_now);
  // Agents that failed to come up or stalled: no longer waited for.
  void GiveUp(RobotId id);

  // --- The lockstep exchange (messages.h ExchangeTick). Exchange points are every
  // exchange_period_s of scenario time; each closes a window. After the barrier of the batch that
  // crosses one, the exchange phase, then the deliver phase (each polled until done), then the
  // holds.
  // The tick of the batch at `stamp`: the index of the last exchange point it crosses, when it
  // crosses one not ticked yet.
  std::optional<std::uint32_t> ExchangeDue(double stamp);
  // After the stream's last batch: the closing tick, one past the last exchange, at the last
  // stamp ExchangeDue saw, so that what was published at the last exchange point is applied
  // too; nullopt when no exchange took place.
  struct Closing {
    std::uint32_t index = 0;
    double stamp = 0.0;
  };
  std::optional<Closing> ClosingExchange() const;
  // The exchange phase of tick `index` at scenario time `stamp` with the latest link table: every
  // agent up or silent listed with its incarnation.
  ExchangeTick BeginExchange(std::uint32_t index, double stamp, const RadioLinks& links, double wall_now);
  // The deliver phase: each listed agent still alive, with what it published at the tick.
  ExchangeTick BeginDeliver(double wall_now);
  struct TickPoll {
    bool done = false;
    bool reissue = false;          // deliver: a listed agent died; send the phase again (BeginDeliver)
    std::vector<RobotId> stalled;  // given up at this poll (no answer for stall_timeout_s)
    std::vector<RobotId> waiting;  // not done: the listed agents that have not answered
  };
  // Done when every listed agent still alive has answered the phase begun last (its status
  // reports the tick done, or delivered).
  TickPoll PollTick(double wall_now);
  const ExchangeTick& tick() const { return tick_; }

  const AgentTracker& tracker() const { return tracker_; }
  const Options& options() const { return options_; }
  std::uint64_t resent() const { return resent_; }
  // Sensor messages replayed to restarted agents (their robots' streams from the start).
  std::uint64_t replayed() const { return replayed_; }

 private:
  Options options_;
  ProcessProbe probe_;
  AgentTracker tracker_;
  SentLog sent_;
  std::uint64_t resent_ = 0;
  StreamLog streams_;
  std::uint64_t replayed_ = 0;
  std::map<RobotId, bool> replay_due_;  // restarted, its replay not begun
  struct Replay {
    std::size_t next = 0;    // the stream's next message to send
    double wait_for = -1.0;  // the last piece's last odometry stamp, to be reported processed
    bool first_sent = false;
  };
  std::map<RobotId, Replay> replays_;                    // replays under way
  std::map<RobotId, std::uint32_t> matches_at_restart_;  // count before the current incarnation
  std::map<RobotId, std::uint32_t> last_matches_;
  std::map<RobotId, Odometry> held_;
  std::map<RobotId, double> published_until_;  // last odometry stamp published per robot
  std::vector<double> holds_;                  // sorted, ascending
  double next_barrier_;
  bool continue_ = false;
  double startup_deadline_ = 0.0;
  double barrier_best_ = -1.0;                  // the lagging agents' summed progress at the last advance
  double barrier_progress_at_ = 0;              // wall time of that advance
  double next_exchange_;                        // the next exchange point (infinite: none)
  std::optional<std::uint32_t> last_exchange_;  // the last tick ExchangeDue gave
  double last_stamp_ = 0.0;                     // the last stamp it saw
  ExchangeTick tick_;                           // the phase begun last
  double tick_begun_at_ = 0.0;                  // wall time it began
  // Listed agents still alive (not dead; a stalled one is given up and so dead).
  std::vector<TickPeer> LiveListed() const;
};

}  // namespace mapmesh
