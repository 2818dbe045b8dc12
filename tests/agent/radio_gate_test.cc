#include "agent/radio_gate.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <vector>

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

// U1: each link has its own latency, latency_s plus a uniform draw in [0, jitter) per pair: both
// ends agree on it, every run of the scenario does, and over many pairs the draws are uniform.
TEST(RadioGate, EachLinkHasItsOwnLatencyBothEndsAgreeOn) {
  RadioGateOptions o;
  o.latency_s = 0.5;
  o.latency_jitter_s = 2.0;
  o.link_seed = 11;
  std::vector<double> draws;
  for (RobotId a = 1; a <= 60; ++a) {
    for (RobotId b = a + 1; b <= 60; ++b) {
      const double l = LinkLatency(o, a, b);
      EXPECT_EQ(l, LinkLatency(o, b, a));
      EXPECT_GE(l, 0.5);
      EXPECT_LT(l, 2.5);
      draws.push_back((l - 0.5) / 2.0);
    }
  }
  // 1770 pairs: the draws' mean within 4 standard errors of 1/2 (sd of U(0,1): 0.289), and
  // each tenth of [0, 1) holds its share within 4 binomial sd.
  double mean = 0.0;
  std::array<int, 10> bins{};
  for (double u : draws) {
    mean += u / static_cast<double>(draws.size());
    ++bins[static_cast<std::size_t>(u * 10.0)];
  }
  EXPECT_NEAR(mean, 0.5, 4.0 * 0.289 / std::sqrt(static_cast<double>(draws.size())));
  const double n = static_cast<double>(draws.size());
  for (int c : bins) EXPECT_NEAR(c, n / 10.0, 4.0 * std::sqrt(n * 0.1 * 0.9));
  // Another seed, other draws; no jitter, latency_s on every link.
  RadioGateOptions other = o;
  other.link_seed = 12;
  EXPECT_NE(LinkLatency(o, 1, 2), LinkLatency(other, 1, 2));
  o.latency_jitter_s = 0.0;
  EXPECT_EQ(LinkLatency(o, 3, 9), 0.5);
}

TEST(RadioGate, AMessageArrivesAfterTheLinksLatencyAndItsTransmissionTime) {
  RadioGateOptions o;
  o.latency_s = 1.5;
  o.latency_jitter_s = 1.0;
  o.link_seed = 3;
  RadioGate g(1, o, 1);
  EXPECT_TRUE(g.Delays());
  EXPECT_DOUBLE_EQ(g.Arrival(2, 5000, 10.0), 10.0 + LinkLatency(o, 1, 2));
  o.bandwidth_bytes_per_s = 1000.0;
  RadioGate slow(2, o, 1);
  EXPECT_DOUBLE_EQ(slow.Arrival(1, 5000, 10.0), 10.0 + LinkLatency(o, 1, 2) + 5.0);  // the same link's
  RadioGate none(1, {}, 1);
  EXPECT_FALSE(none.Delays());
  EXPECT_EQ(none.Arrival(2, 1 << 20, 7.0), 7.0);
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
