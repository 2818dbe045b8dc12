#include "agent/delay_line.h"

#include <gtest/gtest.h>

#include <random>
#include <variant>

namespace mapmesh {
namespace {

MapMessage MapOf(RobotId robot, std::uint32_t version) {
  MapMessage m;
  m.robot_id = robot;
  m.version = version;
  return m;
}

// Messages come out once they have arrived, in order of arrival, then of holding, whatever the
// order they were held in (seeded random arrivals).
TEST(DelayLine, MessagesComeOutOnceArrivedInOrderOfArrivalThenHolding) {
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<int> tenth(0, 40);
  DelayLine line;
  std::vector<std::pair<double, std::uint32_t>> held;  // (arrival, version), in holding order
  for (std::uint32_t v = 1; v <= 300; ++v) {
    const double arrival = 0.1 * tenth(rng);  // many ties
    ASSERT_TRUE(line.Hold(arrival, MapOf(2, v), "w", 10));
    held.push_back({arrival, v});
  }
  std::stable_sort(held.begin(), held.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::size_t next = 0;
  for (double now = 0.0; now <= 4.05; now += 0.25) {
    for (const DelayLine::Message& m : line.TakeArrived(now)) {
      ASSERT_LT(next, held.size());
      EXPECT_LE(held[next].first, now);
      EXPECT_EQ(std::get<DelayLine::HeldMap>(m).map.version, held[next].second);
      ++next;
    }
    // Nothing left that has arrived.
    while (next < held.size() && held[next].first <= now) FAIL() << "arrived but not taken: " << held[next].second;
  }
  EXPECT_EQ(next, held.size());
  EXPECT_EQ(line.size(), 0u);
  EXPECT_EQ(line.bytes(), 0u);
}

TEST(DelayLine, MapsAndSightingsShareOneOrderAndWritersComeBack) {
  DelayLine line;
  Sighting s;
  s.robot_id = 3;
  ASSERT_TRUE(line.Hold(2.0, MapOf(2, 1), "writer-2", 100));
  ASSERT_TRUE(line.Hold(1.0, s));
  EXPECT_TRUE(line.TakeArrived(0.999).empty());
  const auto first = line.TakeArrived(1.0);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(std::get<Sighting>(first[0]).robot_id, 3u);
  EXPECT_EQ(line.bytes(), 100u);
  const auto second = line.TakeArrived(5.0);
  ASSERT_EQ(second.size(), 1u);
  EXPECT_EQ(std::get<DelayLine::HeldMap>(second[0]).writer, "writer-2");
}

// Whatever the latency and the swarm, what it holds is bounded: beyond a bound a message is
// dropped and counted, and room comes back as messages arrive.
TEST(DelayLine, HoldsNoMoreThanItsBounds) {
  DelayLine line({/*max_messages=*/3, /*max_bytes=*/250});
  EXPECT_TRUE(line.Hold(1.0, MapOf(2, 1), "", 100));
  EXPECT_TRUE(line.Hold(2.0, MapOf(2, 2), "", 100));
  EXPECT_FALSE(line.Hold(3.0, MapOf(2, 3), "", 100));  // 300 bytes
  EXPECT_TRUE(line.Hold(3.0, Sighting{}));
  EXPECT_FALSE(line.Hold(4.0, Sighting{}));  // 4 messages
  EXPECT_EQ(line.dropped(), 2u);
  EXPECT_EQ(line.size(), 3u);
  EXPECT_EQ(line.TakeArrived(1.0).size(), 1u);
  EXPECT_TRUE(line.Hold(5.0, MapOf(2, 4), "", 100));
  EXPECT_EQ(line.bytes(), 200u);
}

}  // namespace
}  // namespace mapmesh
