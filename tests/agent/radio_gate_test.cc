#include "agent/radio_gate.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

TEST(RadioGate, NobodyIsInRangeBeforeTheFirstTable) {
  RadioGate g(1, {}, 1);
  EXPECT_EQ(g.Admit(2, 100, 0.0), GateVerdict::kOutOfRange);
}

TEST(RadioGate, FollowsTheLatestTable) {
  RadioGate g(2, {}, 1);
  g.UpdateLinks({1.0, {{1, 2}, {3, 4}}});
  EXPECT_EQ(g.Admit(1, 100, 0.0), GateVerdict::kPass);
  EXPECT_EQ(g.Admit(3, 100, 0.0), GateVerdict::kOutOfRange);  // 3 and 4 hear each other, not us
  g.UpdateLinks({2.0, {{2, 3}}});
  EXPECT_EQ(g.Admit(1, 100, 0.0), GateVerdict::kOutOfRange);
  EXPECT_EQ(g.Admit(3, 100, 0.0), GateVerdict::kPass);
  g.UpdateLinks({1.5, {{1, 2}}});  // older than the current table: ignored
  EXPECT_EQ(g.Admit(1, 100, 0.0), GateVerdict::kOutOfRange);
  g.UpdateLinks({3.0, {}});
  EXPECT_EQ(g.Admit(3, 100, 0.0), GateVerdict::kOutOfRange);
}

TEST(RadioGate, LossRateIsHonoured) {
  RadioGate g(1, {0.3}, 42);
  g.UpdateLinks({0.0, {{1, 2}}});
  int lost = 0;
  const int kN = 20000;
  for (int i = 0; i < kN; ++i) lost += g.Admit(2, 100, 0.0) == GateVerdict::kLost;
  // Binomial(20000, 0.3): sd = 65; allow 5 sd.
  EXPECT_NEAR(lost, 0.3 * kN, 325);
}

TEST(RadioGate, BandwidthKeepsTheLinkBusyForBytesOverRate) {
  RadioGate g(1, {0.0, 1000.0}, 1);  // 1000 bytes/s
  g.UpdateLinks({0.0, {{1, 2}, {1, 3}}});
  EXPECT_EQ(g.Admit(2, 500, 10.0), GateVerdict::kPass);   // busy until 10.5
  EXPECT_EQ(g.Admit(2, 500, 10.4), GateVerdict::kBusy);
  EXPECT_EQ(g.Admit(3, 500, 10.4), GateVerdict::kPass);   // each sender has its own link
  EXPECT_EQ(g.Admit(2, 5000, 10.5), GateVerdict::kPass);  // a large message passes, busy to 15.5
  EXPECT_EQ(g.Admit(2, 10, 15.0), GateVerdict::kBusy);
  EXPECT_EQ(g.Admit(2, 10, 15.5), GateVerdict::kPass);
  RadioGate unlimited(1, {}, 1);
  unlimited.UpdateLinks({0.0, {{1, 2}}});
  for (int i = 0; i < 100; ++i) EXPECT_EQ(unlimited.Admit(2, 1 << 20, 1.0), GateVerdict::kPass);
}

TEST(RadioGate, IsDeterministicForASeed) {
  RadioGate a(1, {0.5}, 7), b(1, {0.5}, 7);
  a.UpdateLinks({0.0, {{1, 2}}});
  b.UpdateLinks({0.0, {{1, 2}}});
  for (int i = 0; i < 100; ++i) EXPECT_EQ(a.Admit(2, 100, 0.0), b.Admit(2, 100, 0.0));
}

}  // namespace
}  // namespace mapmesh
