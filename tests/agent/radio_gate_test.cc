#include "agent/radio_gate.h"

#include <gtest/gtest.h>

#include <limits>

namespace mapmesh {
namespace {

TEST(RadioGate, NobodyIsInRangeBeforeTheFirstTable) {
  RadioGate g(1, {}, 1);
  EXPECT_EQ(g.Admit(2, 100, 0.0), GateVerdict::kOutOfRange);
}

TEST(RadioGate, FollowsTheLatestTable) {
  RadioGate g(2, {}, 1);
  g.UpdateLinks({1.0, {{1, 2}, {3, 4}}}, 1.0);
  EXPECT_EQ(g.Admit(1, 100, 0.0), GateVerdict::kPass);
  EXPECT_EQ(g.Admit(3, 100, 0.0), GateVerdict::kOutOfRange);  // 3 and 4 hear each other, not us
  g.UpdateLinks({2.0, {{2, 3}}}, 2.0);
  EXPECT_EQ(g.Admit(1, 100, 0.0), GateVerdict::kOutOfRange);
  EXPECT_EQ(g.Admit(3, 100, 0.0), GateVerdict::kPass);
  g.UpdateLinks({1.5, {{1, 2}}}, 1.5);  // older than the current table: ignored
  EXPECT_EQ(g.Admit(1, 100, 0.0), GateVerdict::kOutOfRange);
  g.UpdateLinks({3.0, {}}, 3.0);
  EXPECT_EQ(g.Admit(3, 100, 0.0), GateVerdict::kOutOfRange);
}

TEST(RadioGate, LossRateIsHonoured) {
  RadioGate g(1, {0.3}, 42);
  g.UpdateLinks({0.0, {{1, 2}}}, 0.0);
  int lost = 0;
  const int kN = 20000;
  for (int i = 0; i < kN; ++i) lost += g.Admit(2, 100, 0.0) == GateVerdict::kLost;
  // Binomial(20000, 0.3): sd = 65; allow 5 sd.
  EXPECT_NEAR(lost, 0.3 * kN, 325);
}

TEST(RadioGate, BandwidthKeepsTheLinkBusyForBytesOverRate) {
  RadioGate g(1, {0.0, 1000.0}, 1);  // 1000 bytes/s
  g.UpdateLinks({0.0, {{1, 2}, {1, 3}}}, 0.0);
  EXPECT_EQ(g.Admit(2, 500, 10.0), GateVerdict::kPass);  // busy until 10.5
  EXPECT_EQ(g.Admit(2, 500, 10.4), GateVerdict::kBusy);
  EXPECT_EQ(g.Admit(3, 500, 10.4), GateVerdict::kPass);   // each sender has its own link
  EXPECT_EQ(g.Admit(2, 5000, 10.5), GateVerdict::kPass);  // a large message passes, busy to 15.5
  EXPECT_EQ(g.Admit(2, 10, 15.0), GateVerdict::kBusy);
  EXPECT_EQ(g.Admit(2, 10, 15.5), GateVerdict::kPass);
  RadioGate unlimited(1, {}, 1);
  unlimited.UpdateLinks({0.0, {{1, 2}}}, 0.0);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(unlimited.Admit(2, 1 << 20, 1.0), GateVerdict::kPass);
}

TEST(RadioGate, IsDeterministicForASeed) {
  RadioGate a(1, {0.5}, 7), b(1, {0.5}, 7);
  a.UpdateLinks({0.0, {{1, 2}}}, 0.0);
  b.UpdateLinks({0.0, {{1, 2}}}, 0.0);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(a.Admit(2, 100, 0.0), b.Admit(2, 100, 0.0));
}

// A table stamped 1e300 would make every later one look old: it is held, and refused when the
// next genuine table does not confirm it.
TEST(RadioGate, AForgedLinkTableIsRefused) {
  RadioGateOptions o;
  o.max_stamp_jump_s = 5.0;
  RadioGate g(1, o, 1);
  EXPECT_EQ(g.UpdateLinks({1.0, {{1, 2}}}, 1.0), RadioGate::LinksReceipt::kUsed);
  EXPECT_EQ(g.UpdateLinks({1e300, {}}, 1.2), RadioGate::LinksReceipt::kHeld);
  EXPECT_TRUE(g.InRange(2));
  EXPECT_EQ(g.UpdateLinks({1.5, {{1, 3}}}, 1.5), RadioGate::LinksReceipt::kUsed);
  EXPECT_TRUE(g.InRange(3));
  EXPECT_EQ(g.links_refused(), 1u);
  EXPECT_EQ(g.UpdateLinks({2.0, {{1, 2}}}, 2.0), RadioGate::LinksReceipt::kUsed);
  EXPECT_TRUE(g.InRange(2));
  // Non-finite, negative, and (the run's end known) later than the run: refused at once.
  o.max_stamp_s = 100.0;
  RadioGate bounded(1, o, 1);
  for (double bad : {std::numeric_limits<double>::quiet_NaN(), -1.0, 1e300}) {
    EXPECT_EQ(bounded.UpdateLinks({bad, {{1, 2}}}, 0.0), RadioGate::LinksReceipt::kImplausible);
  }
  EXPECT_EQ(bounded.links_refused(), 3u);
  EXPECT_FALSE(bounded.InRange(2));
}

// A genuine jump (the agent was paused while the world went on) is confirmed by the next table.
TEST(RadioGate, AJumpConfirmedByTheNextTableIsUsed) {
  RadioGateOptions o;
  o.max_stamp_jump_s = 5.0;
  RadioGate g(1, o, 1);
  g.UpdateLinks({1.0, {}}, 1.0);
  EXPECT_EQ(g.UpdateLinks({30.0, {{1, 2}}}, 1.0), RadioGate::LinksReceipt::kHeld);
  EXPECT_EQ(g.UpdateLinks({30.5, {{1, 2}}}, 1.0), RadioGate::LinksReceipt::kUsed);
  EXPECT_TRUE(g.InRange(2));
  EXPECT_EQ(g.links_refused(), 0u);
}

}  // namespace
}  // namespace mapmesh
