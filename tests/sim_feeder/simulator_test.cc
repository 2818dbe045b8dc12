#include "sim_feeder/simulator.h"

#include <gtest/gtest.h>

#include "sim_feeder/radio_model.h"
#include "sim_feeder/world.h"

namespace mapmesh {
namespace {

Scenario Small(std::uint64_t seed, int agents = 0, const std::vector<std::string>& overrides = {}) {
  std::vector<ConfigOverride> o{ParseOverride("seed=" + std::to_string(seed))};
  for (const std::string& s : overrides) o.push_back(ParseOverride(s));
  return ParseScenario(R"(version: 1
duration_s: 20
world: {landmarks: {generator: {count: 60, area_m: [0, 0, 30, 30], min_spacing_m: 1}}}
robots:
  count: 3
  defaults: {sensor: {signatures: true}}
radio: {range_m: 15, links_period_s: 1.0}
)",
                       "sim.yaml", o, agents);
}

// Flattens everything a simulator produces, for comparisons.
std::vector<double> Stream(Simulator& sim) {
  std::vector<double> v;
  while (!sim.Done()) {
    const FeedBatch b = sim.Next();
    v.push_back(b.stamp);
    for (const auto& o : b.odom) v.insert(v.end(), {double(o.robot_id), o.v, o.w, double(o.scans_in_interval)});
    for (const auto& s : b.scans) {
      for (const auto& o : s.obs) v.insert(v.end(), {o.range, o.bearing, double(o.signature)});
    }
    for (const auto& t : b.truth) v.insert(v.end(), {t.x, t.y, t.theta});
    if (b.links) v.push_back(double(b.links->links.size()));
  }
  return v;
}

TEST(Simulator, IsDeterministicPerSeed) {
  const Scenario a = Small(3), b = Small(3), c = Small(4);
  Simulator sa(a, BuildWorld(a)), sb(b, BuildWorld(b)), sc(c, BuildWorld(c));
  const auto va = Stream(sa), vb = Stream(sb), vc = Stream(sc);
  EXPECT_EQ(va, vb);
  EXPECT_NE(va, vc);
}

TEST(Simulator, ProducesTheExpectedStreams) {
  const Scenario s = Small(5);
  Simulator sim(s, BuildWorld(s));
  int batches = 0, odom = 0, scans = 0, links = 0;
  double last = -1;
  while (!sim.Done()) {
    const FeedBatch b = sim.Next();
    EXPECT_GT(b.stamp, last);
    last = b.stamp;
    ++batches;
    odom += static_cast<int>(b.odom.size());
    scans += static_cast<int>(b.scans.size());
    links += b.links.has_value();
    for (const auto& o : b.odom) {
      const bool scanned = std::any_of(b.scans.begin(), b.scans.end(),
                                       [&](const Scan& sc) { return sc.robot_id == o.robot_id; });
      EXPECT_EQ(o.scans_in_interval, scanned ? 1u : 0u);
    }
    EXPECT_EQ(b.truth.size(), 3u);
  }
  EXPECT_EQ(batches, 201);   // t = 0, 0.1, ..., 20
  EXPECT_EQ(odom, 200 * 3);  // none at t = 0
  EXPECT_EQ(scans, 40 * 3);  // every 5th step
  EXPECT_EQ(links, 21);      // every second, from t = 0
  EXPECT_NEAR(last, 20.0, 1e-9);
  const auto& seen = sim.Truth().seen;
  EXPECT_GT(std::count(seen.begin(), seen.end(), true), 0);
}

// sensor.scan_at_start: one more scan per robot, from the true start pose at t = 0, announced
// by the robot's first odometry; everything after it comes as every 5th step.
TEST(Simulator, ScansFromTheStartPoseWhenAsked) {
  const Scenario s = Small(5, 0, {"robots.defaults.sensor.scan_at_start=true"});
  Simulator sim(s, BuildWorld(s));
  const FeedBatch first = sim.Next();
  ASSERT_EQ(first.scans.size(), 3u);
  EXPECT_TRUE(first.odom.empty());
  for (const Scan& sc : first.scans) {
    EXPECT_EQ(sc.stamp, 0.0);
    EXPECT_EQ(sc.seq, 0u);
    EXPECT_FALSE(sc.obs.empty());
  }
  const FeedBatch second = sim.Next();
  ASSERT_EQ(second.odom.size(), 3u);
  for (const Odometry& o : second.odom) EXPECT_EQ(o.scans_in_interval, 1u);
  int scans = 3;
  while (!sim.Done()) {
    const FeedBatch b = sim.Next();
    scans += static_cast<int>(b.scans.size());
    for (const Odometry& o : b.odom) EXPECT_EQ(o.scans_in_interval, b.scans.empty() ? 0u : 1u);
  }
  EXPECT_EQ(scans, 41 * 3);
  // Without it the first batch has no scan (the default stream is unchanged).
  const Scenario d = Small(5);
  Simulator plain(d, BuildWorld(d));
  EXPECT_TRUE(plain.Next().scans.empty());
}

TEST(Simulator, ARobotsStreamDoesNotDependOnHowManyRun) {
  const Scenario three = Small(8), five = Small(8, 5);
  Simulator s3(three, BuildWorld(three)), s5(five, BuildWorld(five));
  for (int k = 0; k < 100; ++k) {
    const FeedBatch a = s3.Next(), b = s5.Next();
    ASSERT_EQ(a.truth[1].x, b.truth[1].x);
    if (!a.odom.empty()) {
      ASSERT_EQ(a.odom[2].v, b.odom[2].v);
    }
  }
}

TEST(LinksInRange, PairsWithinRangeOnly) {
  const auto links = LinksInRange({{3, 0, 0}, {1, 5, 0}, {2, 20, 0}}, 10.0);
  ASSERT_EQ(links.size(), 1u);
  EXPECT_EQ(links[0], (Link{1, 3}));
  EXPECT_TRUE(LinksInRange({{1, 0, 0}, {2, 0, 0}}, 0.0).empty());
  EXPECT_EQ(LinksInRange({{1, 0, 0}, {2, 15, 0}, {3, 30, 0}}, 15.0).size(), 2u);
}

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

TEST(Simulator, OdometryNoiseHasTheConfiguredMeanAndSpread) {
  // A robot facing its far waypoint drives straight: commanded v = 0.3, w = 0 throughout,
  // so the odometry is that plus the configured noise.
  const Scenario sc = ParseScenario(R"(duration_s: 2000
world: {landmarks: {list: [[0, 50]]}}
robots:
  list:
    - {id: 1, start: [0, 0, 0], path: {type: waypoints, points: [[100000, 0]]}}
)",
                                    "n.yaml");
  Simulator sim(sc, BuildWorld(sc));
  double sv = 0, sw = 0, sv2 = 0, sw2 = 0;
  int n = 0;
  while (!sim.Done()) {
    for (const Odometry& o : sim.Next().odom) {
      const double dv = o.v - 0.3, dw = o.w;
      sv += dv;
      sw += dw;
      sv2 += dv * dv;
      sw2 += dw * dw;
      ++n;
    }
  }
  ASSERT_EQ(n, 20000);
  const double sigma_v = 0.03, sigma_w = 0.0524;
  EXPECT_NEAR(sv / n, 0.0, 4 * sigma_v / std::sqrt(n));
  EXPECT_NEAR(sw / n, 0.0, 4 * sigma_w / std::sqrt(n));
  // Sample variance within 4 standard errors (sd of s^2 / sigma^2 is sqrt(2 / n) = 1 %).
  EXPECT_NEAR(sv2 / n / (sigma_v * sigma_v), 1.0, 0.04);
  EXPECT_NEAR(sw2 / n / (sigma_w * sigma_w), 1.0, 0.04);
}

}  // namespace
}  // namespace mapmesh
