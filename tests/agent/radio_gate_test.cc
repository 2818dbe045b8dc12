#include "agent/radio_gate.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

TEST(RadioGate, NobodyIsInRangeBeforeTheFirstTable) {
  RadioGate g(1, {}, 1);
  EXPECT_EQ(g.Admit(2), GateVerdict::kOutOfRange);
}

TEST(RadioGate, FollowsTheLatestTable) {
  RadioGate g(2, {}, 1);
  g.UpdateLinks({1.0, {{1, 2}, {3, 4}}});
  EXPECT_EQ(g.Admit(1), GateVerdict::kPass);
  EXPECT_EQ(g.Admit(3), GateVerdict::kOutOfRange);  // 3 and 4 hear each other, not us
  g.UpdateLinks({2.0, {{2, 3}}});
  EXPECT_EQ(g.Admit(1), GateVerdict::kOutOfRange);
  EXPECT_EQ(g.Admit(3), GateVerdict::kPass);
  g.UpdateLinks({1.5, {{1, 2}}});  // older than the current table: ignored
  EXPECT_EQ(g.Admit(1), GateVerdict::kOutOfRange);
  g.UpdateLinks({3.0, {}});
  EXPECT_EQ(g.Admit(3), GateVerdict::kOutOfRange);
}

TEST(RadioGate, LossRateIsHonoured) {
  RadioGate g(1, {0.3}, 42);
  g.UpdateLinks({0.0, {{1, 2}}});
  int lost = 0;
  const int kN = 20000;
  for (int i = 0; i < kN; ++i) lost += g.Admit(2) == GateVerdict::kLost;
  // Binomial(20000, 0.3): sd = 65; allow 5 sd.
  EXPECT_NEAR(lost, 0.3 * kN, 325);
}

TEST(RadioGate, IsDeterministicForASeed) {
  RadioGate a(1, {0.5}, 7), b(1, {0.5}, 7);
  a.UpdateLinks({0.0, {{1, 2}}});
  b.UpdateLinks({0.0, {{1, 2}}});
  for (int i = 0; i < 100; ++i) EXPECT_EQ(a.Admit(2), b.Admit(2));
}

}  // namespace
}  // namespace mapmesh
