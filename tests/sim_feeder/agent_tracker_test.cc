#include "sim_feeder/agent_tracker.h"

#include <gtest/gtest.h>

#include "tests/testing/messages.h"

namespace mapmesh {
namespace {

constexpr auto St = testing::StatusAt;

TEST(AgentTracker, AnAgentIsUpOnceItReportedAndSubscribed) {
  AgentTracker t({1, 2});
  EXPECT_EQ(t.Pending(), (std::vector<RobotId>{1, 2}));
  t.OnStatus(St(1, 10, 0));
  EXPECT_FALSE(t.IsUp(1));
  t.SetSubscribed(1, true);
  EXPECT_TRUE(t.IsUp(1));
  EXPECT_EQ(t.Pending(), std::vector<RobotId>{2});
  t.OnStatus(St(7, 1, 0));  // not in the run: ignored
  EXPECT_EQ(t.Statuses().size(), 1u);
}

TEST(AgentTracker, LaggingListsUpAgentsBehindTheBarrier) {
  AgentTracker t({1, 2});
  for (RobotId id : {1u, 2u}) {
    t.OnStatus(St(id, id, 0.0));
    t.SetSubscribed(id, true);
  }
  t.OnStatus(St(1, 1, 1.0));
  EXPECT_EQ(t.Lagging({{1, 1.0}, {2, 1.0}}), std::vector<RobotId>{2});
  EXPECT_TRUE(t.Lagging({{1, 1.0}, {2, 0.0}}).empty());  // each agent against its own target
  EXPECT_TRUE(t.Lagging({{1, 1.0}}).empty());            // no target: not waited for
  t.OnStatus(St(2, 2, 1.0));
  EXPECT_TRUE(t.Lagging({{1, 1.0}, {2, 1.0}}).empty());
}

TEST(AgentTracker, KilledAgentsAreNotWaitedForAndTheirLateStatusesIgnored) {
  AgentTracker t({1});
  t.OnStatus(St(1, 5, 0.0));
  t.SetSubscribed(1, true);
  t.MarkDead(1);
  EXPECT_TRUE(t.IsDead(1));
  EXPECT_TRUE(t.Lagging({{1, 10.0}}).empty());
  EXPECT_TRUE(t.Pending().empty());
  t.OnStatus(St(1, 5, 0.5));  // in flight when it was killed
  EXPECT_TRUE(t.IsDead(1));
}

TEST(AgentTracker, RestartWaitsForTheNewIncarnation) {
  AgentTracker t({1});
  t.OnStatus(St(1, 5, 3.0));
  t.SetSubscribed(1, true);
  t.MarkDead(1);
  t.ExpectRestart(1);
  EXPECT_EQ(t.Pending(), std::vector<RobotId>{1});
  t.OnStatus(St(1, 5, 3.0));  // the old process
  EXPECT_FALSE(t.IsUp(1));
  t.OnStatus(St(1, 6, 0.0));
  t.SetSubscribed(1, true);
  EXPECT_TRUE(t.IsUp(1));
  EXPECT_EQ(t.Lagging({{1, 3.5}}), std::vector<RobotId>{1});
}

TEST(AgentTracker, LivelinessLossMarksDead) {
  AgentTracker t({1});
  t.OnGone(1);  // never seen: nothing to do
  EXPECT_FALSE(t.IsDead(1));
  t.OnStatus(St(1, 5, 0.0));
  t.SetSubscribed(1, true);
  t.OnGone(1);
  EXPECT_TRUE(t.IsDead(1));
  t.OnStatus(St(1, 9, 0.0));  // an unannounced new process comes back
  t.SetSubscribed(1, true);
  EXPECT_TRUE(t.IsUp(1));
}

// A paused agent's writers go quiet, but its process is still there: it is silent, still
// waited for at every barrier, and up again with its next status (same incarnation). Only when
// its process is gone is it dead.
TEST(AgentTracker, LivelinessLossOfAnExistingProcessIsSilenceNotDeath) {
  AgentTracker t({1, 2});
  for (RobotId id : {1u, 2u}) {
    t.OnStatus(St(id, id, 1.0));
    t.SetSubscribed(id, true);
  }
  t.SetProcess(2, 4242);
  EXPECT_EQ(t.process(2), 4242);
  t.OnGone(2, /*process_exists=*/true);
  EXPECT_TRUE(t.IsSilent(2));
  EXPECT_FALSE(t.IsDead(2));
  EXPECT_FALSE(t.IsUp(2));
  EXPECT_EQ(t.Silent(), std::vector<RobotId>{2});
  EXPECT_EQ(t.Lagging({{1, 2.0}, {2, 2.0}}), (std::vector<RobotId>{1, 2}));  // still waited for
  EXPECT_TRUE(t.Pending().empty());
  t.OnStatus(St(2, 2, 2.0));  // SIGCONT: the same process speaks again
  EXPECT_TRUE(t.IsUp(2));
  EXPECT_FALSE(t.IsSilent(2));
  EXPECT_EQ(t.Lagging({{1, 2.0}, {2, 2.0}}), std::vector<RobotId>{1});
  // Quiet again, and this time the process is gone: dead, and no longer waited for.
  t.OnGone(2, true);
  t.OnProcessGone(2);
  EXPECT_TRUE(t.IsDead(2));
  EXPECT_FALSE(t.IsSilent(2));
  EXPECT_EQ(t.Lagging({{1, 2.0}, {2, 3.0}}), std::vector<RobotId>{1});
}

TEST(ParseControl, Commands) {
  EXPECT_EQ(ParseControl("dead 3")->kind, ControlCommand::Kind::kDead);
  EXPECT_EQ(ParseControl("dead 3")->id, 3u);
  EXPECT_EQ(ParseControl("expect 12")->kind, ControlCommand::Kind::kExpect);
  EXPECT_EQ(ParseControl("continue")->kind, ControlCommand::Kind::kContinue);
  EXPECT_EQ(ParseControl("stop")->kind, ControlCommand::Kind::kStop);
  EXPECT_EQ(ParseControl("pid 2 31337")->kind, ControlCommand::Kind::kPid);
  EXPECT_EQ(ParseControl("pid 2 31337")->pid, 31337);
  EXPECT_FALSE(ParseControl("pid 2").has_value());
  EXPECT_FALSE(ParseControl("pid 2 -5").has_value());
  EXPECT_FALSE(ParseControl("dead").has_value());
  EXPECT_FALSE(ParseControl("dead -1").has_value());
  EXPECT_FALSE(ParseControl("launch 2").has_value());
  EXPECT_FALSE(ParseControl("").has_value());
}

}  // namespace
}  // namespace mapmesh
