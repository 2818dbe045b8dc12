// The radio models (U1): the log-distance model's link frequencies against its closed form over
// seeded positions and a wall, the disc as its limit, walls, the draws' determinism, and the
// spans feeder.json records.
#include "sim_feeder/radio_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <tuple>

namespace mapmesh {
namespace {

RadioOptions LogDistance(double range_m, double sigma_db, double width_db, std::vector<RadioWall> walls = {}) {
  RadioOptions o;
  o.model = RadioModelKind::kLogDistance;
  o.range_m = range_m;
  o.shadowing_sigma_db = sigma_db;
  o.packet_error_width_db = width_db;
  o.walls = std::move(walls);
  return o;
}

bool Linked(const std::vector<Link>& links, RobotId a, RobotId b) {
  for (const Link& l : links) {
    if (l.a == a && l.b == b) return true;
  }
  return false;
}

TEST(RadioModel, LinkFrequenciesMatchTheClosedFormOverSeededPositionsAndAWall) {
  // A wall across the middle of a 60 m square; robot pairs drawn in it. Each table falls in a
  // shadowing period of its own, so the tables are independent draws of the link.
  const std::vector<RadioWall> walls{{{30.0, -10.0}, {30.0, 70.0}}};
  const RadioOptions o = LogDistance(25.0, 6.0, 2.0, walls);
  const RadioModel radio(o, 20261204);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> at(0.0, 60.0);
  int behind_walls = 0;
  const int tables = 4000;
  for (int pair = 0; pair < 24; ++pair) {
    const RobotPosition p{1, at(rng), at(rng)}, q{2, at(rng), at(rng)};
    const double d = std::hypot(p.x - q.x, p.y - q.y);
    const int k = WallsCrossed(walls, {p.x, p.y}, {q.x, q.y});
    behind_walls += k;
    const double expected = radio.UpProbability(d, k);
    EXPECT_NEAR(expected,
                0.5 * std::erfc(-(-30.0 * std::log10(d / 25.0) - 6.9 * k) / std::hypot(6.0, 2.0) / std::sqrt(2.0)),
                1e-12);
    int up = 0;
    for (int t = 0; t < tables; ++t) up += Linked(radio.Links({p, q}, t * o.shadowing_period_s), 1, 2) ? 1 : 0;
    const double se = std::sqrt(expected * (1.0 - expected) / tables);
    EXPECT_NEAR(static_cast<double>(up) / tables, expected, 4.0 * se + 1e-3) << "d " << d << " walls " << k;
  }
  EXPECT_GT(behind_walls, 4);  // the wall was between some of the pairs
}

TEST(RadioModel, WithinAShadowingPeriodOnlyThePacketDrawVaries) {
  // sigma only: one draw per period, so every table of a period agrees.
  const RadioOptions o = LogDistance(20.0, 8.0, 0.0);
  const RadioModel radio(o, 3);
  const std::vector<RobotPosition> two{{1, 0, 0}, {2, 20, 0}};
  int changes = 0;
  for (int period = 0; period < 50; ++period) {
    const bool first = !radio.Links(two, period * o.shadowing_period_s).empty();
    for (double dt = 0.5; dt < o.shadowing_period_s; dt += 0.5) {
      ASSERT_EQ(!radio.Links(two, period * o.shadowing_period_s + dt).empty(), first);
    }
    changes += first != !radio.Links(two, (period + 1) * o.shadowing_period_s).empty();
  }
  EXPECT_GT(changes, 5);  // and the periods differ (at range_m: up half the time)
}

TEST(RadioModel, WithoutSpreadOrWallsItIsTheDisc) {
  const RadioModel radio(LogDistance(15.0, 0.0, 0.0), 1);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> at(0.0, 40.0);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<RobotPosition> robots;
    for (RobotId id = 1; id <= 6; ++id) robots.push_back({id, at(rng), at(rng)});
    EXPECT_EQ(radio.Links(robots, trial * 0.5), LinksInRange(robots, 15.0));
  }
  RadioOptions disc;
  disc.range_m = 15.0;
  const RadioModel plain(disc, 1);
  EXPECT_EQ(plain.Links({{1, 0, 0}, {2, 10, 0}}, 0.0), (std::vector<Link>{{1, 2}}));
  EXPECT_EQ(plain.UpProbability(10.0, 0), 1.0);
  EXPECT_EQ(plain.UpProbability(16.0, 0), 0.0);
}

TEST(RadioModel, AWallBlocksTheDiscAndCostsTheLogDistanceModelItsLoss) {
  RadioOptions disc;
  disc.range_m = 30.0;
  disc.walls = {{{5.0, -1.0}, {5.0, 1.0}}};
  const RadioModel radio(disc, 1);
  const std::vector<RobotPosition> robots{{1, 0, 0}, {2, 10, 0}, {3, 0, 5}};
  EXPECT_EQ(radio.Links(robots, 0.0), (std::vector<Link>{{1, 3}, {2, 3}}));  // 1-2 through the wall
  EXPECT_EQ(radio.UpProbability(10.0, 1), 0.0);
  const RadioModel lossy(LogDistance(30.0, 0.0, 0.0, disc.walls), 1);
  EXPECT_NEAR(lossy.Margin(10.0, 1), -30.0 * std::log10(10.0 / 30.0) - 6.9, 1e-12);
  EXPECT_TRUE(std::isinf(lossy.Margin(0.0, 0)));
  RadioOptions none = LogDistance(0.0, 6.0, 2.0);
  EXPECT_TRUE(RadioModel(none, 1).Links({{1, 0, 0}, {2, 0, 0}}, 0.0).empty());  // range 0: nobody
}

TEST(RadioModel, WallsCrossedCountsCrossingsAndTouches) {
  const std::vector<RadioWall> walls{{{1, -1}, {1, 1}}, {{2, -1}, {2, 1}}, {{0, 2}, {3, 2}}};
  EXPECT_EQ(WallsCrossed(walls, {0, 0}, {3, 0}), 2);
  EXPECT_EQ(WallsCrossed(walls, {0, 0}, {1, 0}), 1);      // ends on a wall
  EXPECT_EQ(WallsCrossed(walls, {0, 1.5}, {3, 1.5}), 0);  // passes above two, below one
  EXPECT_EQ(WallsCrossed(walls, {0.5, 2}, {2.5, 2}), 1);  // along a wall
  EXPECT_EQ(WallsCrossed(walls, {1.5, -5}, {1.5, 5}), 1);
}

TEST(RadioModel, DrawsAreFunctionsOfSeedPairAndStamp) {
  const RadioOptions o = LogDistance(20.0, 6.0, 2.0);
  std::vector<RobotPosition> robots;
  for (RobotId id = 1; id <= 8; ++id) robots.push_back({id, 3.0 * id, 0.0});
  const RadioModel a(o, 5), b(o, 5), c(o, 6);
  std::vector<RobotPosition> reversed(robots.rbegin(), robots.rend());
  int differ = 0;
  for (int t = 0; t < 40; ++t) {
    const auto links = a.Links(robots, t * 0.5);
    EXPECT_EQ(links, b.Links(reversed, t * 0.5));  // order of the robots does not matter
    differ += links != c.Links(robots, t * 0.5);
  }
  EXPECT_GT(differ, 0);
  // The standard normal draws: mean 0, variance 1.
  double sum = 0.0, sq = 0.0;
  const int n = 200000;
  for (int k = 0; k < n; ++k) {
    const double z = NormalDraw(static_cast<std::uint64_t>(k) * 0x9e3779b97f4a7c15ULL);
    sum += z;
    sq += z * z;
  }
  EXPECT_NEAR(sum / n, 0.0, 4.0 / std::sqrt(n));
  EXPECT_NEAR(sq / n, 1.0, 4.0 * std::sqrt(2.0 / n));
}

TEST(LinkSpans, AnUnbrokenRowOfTablesIsOneSpan) {
  LinkSpans spans(0.5);
  spans.Add({0.0, {{1, 2}}});
  spans.Add({0.5, {{1, 2}, {2, 3}}});
  spans.Add({1.0, {{2, 3}}});
  spans.Add({1.5, {{1, 2}}});
  ASSERT_EQ(spans.spans().size(), 3u);
  EXPECT_EQ(spans.tables(), 4u);
  const auto& s = spans.spans();
  EXPECT_EQ((std::tuple(s[0].a, s[0].b, s[0].start, s[0].end)), (std::tuple(1u, 2u, 0.0, 1.0)));
  EXPECT_EQ((std::tuple(s[1].a, s[1].b, s[1].start, s[1].end)), (std::tuple(2u, 3u, 0.5, 1.5)));
  EXPECT_EQ((std::tuple(s[2].a, s[2].b, s[2].start, s[2].end)), (std::tuple(1u, 2u, 1.5, 2.0)));
}

}  // namespace
}  // namespace mapmesh
