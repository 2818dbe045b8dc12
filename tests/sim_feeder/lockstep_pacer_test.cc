#include "sim_feeder/lockstep_pacer.h"

#include <gtest/gtest.h>

#include <map>

#include "tests/testing/messages.h"

namespace mapmesh {
namespace {

constexpr auto St = testing::StatusAt;
constexpr auto Od = testing::OdometryAt;
constexpr auto Sc = testing::ScanAt;

// A pacer over robots 1 and 2 whose processes (pids 101, 102) are in `procs`.
class LockstepPacerTest : public ::testing::Test {
 protected:
  LockstepPacer Make(bool lockstep = true, std::vector<double> holds = {}, double exchange_period_s = 0.0) {
    LockstepPacer::Options o;
    o.lockstep = lockstep;
    o.window_s = 1.0;
    o.stall_timeout_s = 10.0;
    o.holds = std::move(holds);
    o.exchange_period_s = exchange_period_s;
    return LockstepPacer({1, 2}, o,
                         [this](int pid) { return procs_.count(pid) ? procs_.at(pid) : ProcessState::kGone; });
  }
  // Both agents report, are subscribed and have told their processes.
  void BringUp(LockstepPacer& p) {
    for (RobotId id : {1u, 2u}) {
      procs_[100 + static_cast<int>(id)] = ProcessState::kRunning;
      p.OnControl({ControlCommand::Kind::kPid, id, 100 + static_cast<int>(id)}, 0);
      p.OnStatus(St(id, id, 0.0));
      EXPECT_TRUE(p.OnMatches(id, 1).empty());
    }
  }
  std::map<int, ProcessState> procs_;
};

TEST_F(LockstepPacerTest, StartupEndsWhenEveryAgentIsUpOrTheTimeoutPasses) {
  LockstepPacer p = Make();
  p.BeginStartup(100.0, 5.0);
  EXPECT_FALSE(p.PollStartup(101.0));
  p.OnStatus(St(1, 1, 0.0));
  p.OnMatches(1, 1);
  EXPECT_FALSE(p.PollStartup(104.0));  // 2 still pending
  const auto failed = p.PollStartup(105.0);
  ASSERT_TRUE(failed);
  EXPECT_EQ(*failed, std::vector<RobotId>{2});
  p.OnStatus(St(2, 2, 0.0));
  p.OnMatches(2, 1);
  ASSERT_TRUE(p.PollStartup(105.0));
  EXPECT_TRUE(p.PollStartup(105.0)->empty());
}

TEST_F(LockstepPacerTest, LockstepHoldsBackEachRobotsLatestOdometryUntilTheWindowCloses) {
  LockstepPacer p = Make();
  EXPECT_FALSE(p.Admit(Od(1, 0.25)));
  EXPECT_FALSE(p.Admit(Od(2, 0.25)));
  const std::optional<Odometry> first = p.Admit(Od(1, 0.5));
  ASSERT_TRUE(first);
  EXPECT_DOUBLE_EQ(first->stamp, 0.25);
  EXPECT_FALSE(first->sync);
  EXPECT_FALSE(p.IsBarrier(0.5, false));
  EXPECT_TRUE(p.IsBarrier(1.0, false));
  p.Admit(Od(1, 1.0));
  const std::vector<Odometry> closing = p.CloseWindow(1.0);
  ASSERT_EQ(closing.size(), 2u);  // each robot's last message before the barrier, flagged
  for (const Odometry& o : closing) EXPECT_TRUE(o.sync);
  EXPECT_DOUBLE_EQ(closing[0].stamp, 1.0);
  EXPECT_DOUBLE_EQ(closing[1].stamp, 0.25);
  EXPECT_TRUE(p.CloseWindow(1.0).empty());
  EXPECT_FALSE(p.IsBarrier(1.5, false));  // the next window ends at 2
  EXPECT_TRUE(p.IsBarrier(1.5, true));    // the last batch always closes one
  EXPECT_TRUE(p.IsBarrier(2.0, false));
}

TEST_F(LockstepPacerTest, RealTimePublishesOdometryAtOnce) {
  LockstepPacer p = Make(/*lockstep=*/false);
  const std::optional<Odometry> now = p.Admit(Od(1, 0.25));
  ASSERT_TRUE(now);
  EXPECT_FALSE(now->sync);
  EXPECT_TRUE(p.CloseWindow(1.0).empty());
}

TEST_F(LockstepPacerTest, HoldPointsCloseAWindowAndAreTakenOnce) {
  LockstepPacer p = Make(true, {2.5, 0.5, 0.5});
  EXPECT_TRUE(p.IsBarrier(0.5, false));
  EXPECT_EQ(p.TakeHolds(0.5), 2);
  EXPECT_FALSE(p.IsBarrier(0.75, false));
  EXPECT_EQ(p.TakeHolds(0.75), 0);
  EXPECT_TRUE(p.IsBarrier(2.5, false));
  p.BeginHold();
  EXPECT_FALSE(p.HoldReleased());
  p.OnControl({ControlCommand::Kind::kContinue}, 0);
  EXPECT_TRUE(p.HoldReleased());
}

TEST_F(LockstepPacerTest, BarrierWaitsForWhatWasPublishedToEachAgent) {
  LockstepPacer p = Make();
  BringUp(p);
  p.Published(Od(1, 1.0));
  p.Published(Od(2, 0.75));
  p.BeginBarrier(0.0);
  EXPECT_FALSE(p.PollBarrier(0.1).done);
  p.OnStatus(St(1, 1, 1.0));
  EXPECT_FALSE(p.PollBarrier(0.2).done);
  p.OnStatus(St(2, 2, 0.75));
  const LockstepPacer::BarrierPoll poll = p.PollBarrier(0.3);
  EXPECT_TRUE(poll.done);
  EXPECT_TRUE(poll.stalled.empty());
}

TEST_F(LockstepPacerTest, AnAgentWithoutProgressIsGivenUpAndForgotten) {
  LockstepPacer p = Make();
  BringUp(p);
  p.Published(Od(1, 1.0));
  p.Published(Od(2, 1.0));
  p.OnStatus(St(1, 1, 1.0));
  p.BeginBarrier(0.0);
  EXPECT_FALSE(p.PollBarrier(5.0).done);
  p.OnStatus(St(2, 2, 0.5));  // progress restarts the clock
  EXPECT_FALSE(p.PollBarrier(8.0).done);
  EXPECT_FALSE(p.PollBarrier(17.9).done);
  const LockstepPacer::BarrierPoll poll = p.PollBarrier(18.1);
  EXPECT_TRUE(poll.done);
  EXPECT_EQ(poll.stalled, std::vector<RobotId>{2});
  EXPECT_TRUE(p.tracker().IsDead(2));
  // What was sent to it is forgotten: a late re-match sends nothing.
  EXPECT_TRUE(p.OnMatches(2, 2).empty());
  EXPECT_EQ(p.resent(), 0u);
}

TEST_F(LockstepPacerTest, AStoppedAgentIsWaitedForAsLongAsItIsStopped) {
  LockstepPacer p = Make();
  BringUp(p);
  p.Published(Od(2, 1.0));
  procs_[102] = ProcessState::kStopped;
  p.BeginBarrier(0.0);
  EXPECT_FALSE(p.PollBarrier(100.0).done);
  procs_[102] = ProcessState::kRunning;
  EXPECT_FALSE(p.PollBarrier(105.0).done);
  EXPECT_EQ(p.PollBarrier(110.5).stalled, std::vector<RobotId>{2});
}

TEST_F(LockstepPacerTest, AnAgentMatchedAnewWithoutRestartGetsWhatItHasNotProcessed) {
  LockstepPacer p = Make();
  BringUp(p);
  p.Published(Od(1, 0.5));
  p.Published(Sc(1, 0.75));
  p.Published(Od(1, 1.0));
  p.OnStatus(St(1, 1, 0.5));               // processed the first
  EXPECT_TRUE(p.OnMatches(1, 1).empty());  // same match count: nothing
  const std::vector<SentLog::Message> again = p.OnMatches(1, 2);
  ASSERT_EQ(again.size(), 2u);
  EXPECT_TRUE(std::holds_alternative<Scan>(again[0]));
  EXPECT_DOUBLE_EQ(std::get<Odometry>(again[1]).stamp, 1.0);
  EXPECT_EQ(p.resent(), 2u);
}

TEST_F(LockstepPacerTest, ARestartedAgentIsNotResentWhatItsPredecessorMissed) {
  LockstepPacer p = Make();
  BringUp(p);
  p.Published(Od(1, 1.0));
  p.OnControl({ControlCommand::Kind::kDead, 1}, 1);
  p.OnControl({ControlCommand::Kind::kExpect, 1}, 1);
  EXPECT_EQ(p.tracker().Pending(), std::vector<RobotId>{1});
  p.OnStatus(St(1, 7, 0.0));
  EXPECT_TRUE(p.OnMatches(1, 2).empty());  // the new incarnation's first match
  EXPECT_TRUE(p.tracker().IsUp(1));
  EXPECT_EQ(p.resent(), 0u);
}

// A restarted agent is sent its robot's whole stream again, in pieces of at most replay_span_s,
// each once it reported the last processed; until the replay is done it is not up for startup.
TEST_F(LockstepPacerTest, ARestartedAgentIsReplayedItsWholeStreamInPieces) {
  for (const bool lockstep : {true, false}) {
    SCOPED_TRACE(lockstep ? "lockstep" : "realtime");
    LockstepPacer::Options o;
    o.lockstep = lockstep;
    o.replay_span_s = 2.0;
    LockstepPacer p({1, 2}, o, [](int) { return ProcessState::kRunning; });
    for (RobotId id : {1u, 2u}) {
      p.OnStatus(St(id, 1, 0.0));
      p.OnMatches(id, 1);
    }
    // Robot 1's stream: a scan then an odometry each 0.5 s, the odometry closing each second
    // flagged sync; robot 2's does not concern it.
    std::vector<double> odometry;
    for (int k = 1; k <= 12; ++k) {
      const double t = 0.5 * k;
      p.Published(Sc(1, t - 0.25));
      Odometry od = Od(1, t);
      od.sync = k % 2 == 0;
      p.Published(od);
      odometry.push_back(t);
      p.Published(Od(2, t));
    }
    p.OnControl({ControlCommand::Kind::kDead, 1}, 1);
    p.OnControl({ControlCommand::Kind::kExpect, 1}, 1);
    EXPECT_TRUE(p.ReplayDue(1).empty());  // not matched yet
    p.OnStatus(St(1, 2, 0.0));
    EXPECT_TRUE(p.OnMatches(1, 2).empty());  // the pause path sends nothing
    p.BeginStartup(0.0, 100.0);
    std::vector<double> got;
    int pieces = 0;
    double last_odometry = 0.0;
    while (true) {
      EXPECT_FALSE(p.PollStartup(1.0).has_value()) << "up before its replay is done";
      const std::vector<SentLog::Message> piece = p.ReplayDue(1);
      if (piece.empty()) break;
      ++pieces;
      EXPECT_TRUE(p.ReplayDue(1).empty()) << "the next piece before this one is processed";
      const double first = std::visit([](const auto& x) { return x.stamp; }, piece.front());
      for (const SentLog::Message& m : piece) {
        const double t = std::visit([](const auto& x) { return x.stamp; }, m);
        EXPECT_LE(t, first + 2.0);
        if (const auto* od = std::get_if<Odometry>(&m)) {
          EXPECT_EQ(od->robot_id, 1u);
          got.push_back(t);
          last_odometry = t;
        }
      }
      // Each piece ends on an odometry that closed a window (the agent reports it at once).
      const auto* end = std::get_if<Odometry>(&piece.back());
      ASSERT_NE(end, nullptr);
      EXPECT_TRUE(end->sync);
      p.OnStatus(St(1, 2, last_odometry));
    }
    EXPECT_EQ(got, odometry);  // everything, in order, once
    EXPECT_EQ(pieces, 3);      // 0.25-2.0, 2.25-4.0, 4.25-6.0
    EXPECT_EQ(p.replayed(), 24u);
    ASSERT_TRUE(p.PollStartup(1.0).has_value());
    EXPECT_TRUE(p.PollStartup(1.0)->empty());
    EXPECT_EQ(p.resent(), 0u);
  }
}

// feeder.keep_streams false: a restarted agent joins the stream where it is.
TEST_F(LockstepPacerTest, WithoutKeptStreamsARestartedAgentIsNotReplayed) {
  LockstepPacer::Options o;
  o.keep_streams = false;
  LockstepPacer p({1}, o, [](int) { return ProcessState::kRunning; });
  p.OnStatus(St(1, 1, 0.0));
  p.OnMatches(1, 1);
  p.Published(Od(1, 0.5));
  p.OnControl({ControlCommand::Kind::kExpect, 1}, 1);
  p.OnStatus(St(1, 2, 0.0));
  p.OnMatches(1, 2);
  EXPECT_TRUE(p.ReplayDue(1).empty());
  p.BeginStartup(0.0, 100.0);
  ASSERT_TRUE(p.PollStartup(1.0).has_value());
  EXPECT_EQ(p.replayed(), 0u);
}

TEST_F(LockstepPacerTest, RealTimeKeepsNothingToResend) {
  LockstepPacer p = Make(/*lockstep=*/false);
  BringUp(p);
  p.Published(Od(1, 1.0));
  EXPECT_TRUE(p.OnMatches(1, 2).empty());
}

TEST_F(LockstepPacerTest, LostLivelinessIsSilenceWhileTheProcessExistsThenDeath) {
  LockstepPacer p = Make();
  BringUp(p);
  p.Published(Od(2, 1.0));
  const std::optional<bool> exists = p.OnStatusGone(2);
  ASSERT_TRUE(exists);
  EXPECT_TRUE(*exists);
  EXPECT_TRUE(p.tracker().IsSilent(2));
  EXPECT_FALSE(p.OnStatusGone(2));  // nothing new
  EXPECT_TRUE(p.ReapSilent().empty());
  EXPECT_TRUE(p.OnStatus(St(2, 2, 0.5)));  // speaks again
  EXPECT_FALSE(p.tracker().IsSilent(2));
  ASSERT_TRUE(p.OnStatusGone(2));
  procs_.erase(102);
  EXPECT_EQ(p.ReapSilent(), std::vector<RobotId>{2});
  EXPECT_TRUE(p.tracker().IsDead(2));
  p.BeginBarrier(0.0);
  EXPECT_TRUE(p.PollBarrier(0.0).done);  // a dead agent is not waited for
}

TEST_F(LockstepPacerTest, LostLivelinessWithoutAProcessIsDeath) {
  LockstepPacer p = Make();
  p.OnStatus(St(1, 1, 0.0));
  p.OnMatches(1, 1);
  const std::optional<bool> exists = p.OnStatusGone(1);
  ASSERT_TRUE(exists);
  EXPECT_FALSE(*exists);
  EXPECT_TRUE(p.tracker().IsDead(1));
  EXPECT_FALSE(p.OnStatusGone(7));  // not in the run
}

// ----- the lockstep exchange ------------------------------------------------------------------

AgentStatus Answered(RobotId id, std::uint32_t incarnation, std::uint32_t done, std::uint32_t published,
                     std::uint32_t delivered) {
  AgentStatus s = testing::StatusAt(id, incarnation, 0.0);
  s.tick_done = done;
  s.tick_published = published;
  s.tick_delivered = delivered;
  return s;
}

TEST_F(LockstepPacerTest, ExchangePointsCloseWindowsAndEachIsTickedOnceByItsLastIndex) {
  LockstepPacer p = Make(true, {}, 2.5);
  p.CloseWindow(2.0);  // the windows (1 s) close at 3, 4, ...
  EXPECT_FALSE(p.IsBarrier(2.4, false));
  EXPECT_TRUE(p.IsBarrier(2.5, false));  // ... and at the exchange point between
  EXPECT_FALSE(p.ExchangeDue(2.4));
  EXPECT_EQ(p.ExchangeDue(2.5), 1u);
  EXPECT_FALSE(p.ExchangeDue(2.6));
  EXPECT_FALSE(p.IsBarrier(2.6, false));  // ticked: no barrier until the next window
  // A batch past two points at once (a gap in the data) ticks the last one.
  EXPECT_EQ(p.ExchangeDue(8.0), 3u);
  EXPECT_FALSE(p.ExchangeDue(9.9));
  EXPECT_EQ(p.ExchangeDue(10.0), 4u);
  // The stream ends at 11: the closing tick is one past the last, at the last stamp seen.
  EXPECT_FALSE(p.ExchangeDue(11.0));
  ASSERT_TRUE(p.ClosingExchange());
  EXPECT_EQ(p.ClosingExchange()->index, 5u);
  EXPECT_DOUBLE_EQ(p.ClosingExchange()->stamp, 11.0);
  // In real time there are none, and no closing tick.
  LockstepPacer rt = Make(false, {}, 2.5);
  EXPECT_FALSE(rt.ExchangeDue(100.0));
  EXPECT_FALSE(rt.ClosingExchange());
  // Nor before a first exchange.
  EXPECT_FALSE(Make(true, {}, 2.5).ClosingExchange());
}

TEST_F(LockstepPacerTest, AnExchangeListsTheLiveAgentsAndEndsWhenEachHasDoneIt) {
  LockstepPacer p = Make(true, {}, 2.0);
  BringUp(p);
  const ExchangeTick t = p.BeginExchange(1, 2.0, {1.5, {{1, 2}}}, 0.0);
  EXPECT_EQ(t.index, 1u);
  EXPECT_EQ(t.phase, TickPhase::kExchange);
  EXPECT_DOUBLE_EQ(t.links.stamp, 1.5);
  EXPECT_EQ(t.links.links, (std::vector<Link>{{1, 2}}));
  EXPECT_EQ(t.peers, (std::vector<TickPeer>{{1, 1, 0}, {2, 2, 0}}));
  EXPECT_FALSE(p.PollTick(1.0).done);
  p.OnStatus(Answered(1, 1, 1, 5, 0));
  LockstepPacer::TickPoll poll = p.PollTick(1.0);
  EXPECT_FALSE(poll.done);
  EXPECT_EQ(poll.waiting, std::vector<RobotId>{2});
  p.OnStatus(Answered(2, 2, 1, 3, 0));
  EXPECT_TRUE(p.PollTick(1.0).done);
  // The deliver phase lists what each published, and ends when each has it all.
  const ExchangeTick d = p.BeginDeliver(2.0);
  EXPECT_EQ(d.phase, TickPhase::kDeliver);
  EXPECT_EQ(d.peers, (std::vector<TickPeer>{{1, 1, 5}, {2, 2, 3}}));
  EXPECT_FALSE(p.PollTick(2.0).done);
  p.OnStatus(Answered(1, 1, 1, 5, 1));
  p.OnStatus(Answered(2, 2, 1, 3, 1));
  EXPECT_TRUE(p.PollTick(2.0).done);
}

TEST_F(LockstepPacerTest, ADeadAgentIsNotWaitedForAndItsMessagesAreNoLongerExpected) {
  LockstepPacer p = Make(true, {}, 2.0);
  BringUp(p);
  p.BeginExchange(1, 2.0, {-1.0, {}}, 0.0);
  p.OnStatus(Answered(1, 1, 1, 5, 0));
  p.OnStatus(Answered(2, 2, 1, 3, 0));
  ASSERT_TRUE(p.PollTick(1.0).done);
  p.BeginDeliver(1.0);
  // Agent 2 is killed before its messages arrived: the phase is sent again without it.
  p.OnControl({ControlCommand::Kind::kDead, 2, 0}, 0);
  const LockstepPacer::TickPoll poll = p.PollTick(1.5);
  EXPECT_TRUE(poll.reissue);
  EXPECT_FALSE(poll.done);
  const ExchangeTick again = p.BeginDeliver(1.5);
  EXPECT_EQ(again.peers, (std::vector<TickPeer>{{1, 1, 5}}));
  p.OnStatus(Answered(1, 1, 1, 5, 1));
  EXPECT_TRUE(p.PollTick(2.0).done);
  // The next exchange lists the live only.
  EXPECT_EQ(p.BeginExchange(2, 4.0, {-1.0, {}}, 3.0).peers, (std::vector<TickPeer>{{1, 1, 0}}));
}

TEST_F(LockstepPacerTest, ATickWaitsForAStoppedAgentAndGivesUpOneThatStalls) {
  LockstepPacer p = Make(true, {}, 2.0);
  BringUp(p);
  p.BeginExchange(1, 2.0, {-1.0, {}}, 0.0);
  p.OnStatus(Answered(1, 1, 1, 2, 0));
  procs_[102] = ProcessState::kStopped;  // paused: waited for as long as it is stopped
  EXPECT_FALSE(p.PollTick(50.0).done);
  EXPECT_TRUE(p.PollTick(50.0).stalled.empty());
  procs_[102] = ProcessState::kRunning;  // running, but never answers
  EXPECT_FALSE(p.PollTick(55.0).done);
  const LockstepPacer::TickPoll poll = p.PollTick(61.0);
  EXPECT_TRUE(poll.done);
  EXPECT_EQ(poll.stalled, std::vector<RobotId>{2});
  EXPECT_TRUE(p.tracker().IsDead(2));
}

}  // namespace
}  // namespace mapmesh