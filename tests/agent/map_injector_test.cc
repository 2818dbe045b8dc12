#include "agent/map_injector.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <set>

#include "common/map/map_codec.h"
#include "common/map/map_faults.h"
#include "common/map/submap_codec.h"

namespace mapmesh {
namespace {

MapMessage RobotMap(RobotId robot, std::uint32_t version, int landmarks) {
  std::mt19937_64 rng(robot * 100 + version);
  std::uniform_real_distribution<double> u(0.0, 30.0);
  LandmarkMap m;
  for (int i = 0; i < landmarks; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(i);
    l.mean = {u(rng), u(rng)};
    l.cov = Eigen::Matrix2d::Identity() * 0.04;
    m.landmarks.push_back(l);
  }
  MapMessage msg;
  msg.robot_id = robot;
  msg.kind = MapKind::kLocal;
  msg.incarnation = 7;
  msg.version = version;
  msg.stamp = version;
  msg.payload = EncodeMap(m);
  return msg;
}

// The next message, which these cases make maps only.
std::optional<MapMessage> NextMap(MapInjector& inj) {
  const std::optional<InjectedMessage> m = inj.Next();
  if (!m) return std::nullopt;
  return std::get<MapMessage>(*m);
}

TEST(InjectCases, ParsesAllAListAndRefusesUnknownOnes) {
  EXPECT_EQ(ParseInjectCases("all"), AllInjectCases());
  EXPECT_EQ(AllInjectCases().size(), static_cast<std::size_t>(kPayloadFaultCount + 14));
  EXPECT_EQ(ParseInjectCases("shuffled,truncated,shuffled"), (std::vector<std::string>{"shuffled", "truncated"}));
  EXPECT_FALSE(ParseInjectCases("shuffle").has_value());
  EXPECT_FALSE(ParseInjectCases("").has_value());
  EXPECT_FALSE(ParseInjectCases("truncated,,bogus").has_value());
}

TEST(MapInjector, BeforeHearingAnyMapOnlyMalformedAndForeignMapsAreMade) {
  std::vector<std::string> map_cases;
  for (int i = 0; i < kPayloadFaultCount; ++i) map_cases.emplace_back(ToString(static_cast<PayloadFault>(i)));
  for (const char* c : {"stale_version", "unknown_sender", "shuffled"}) map_cases.emplace_back(c);
  MapInjector inj({1, 2}, map_cases, 99, 3);
  std::map<std::string, int> made;
  for (int i = 0; i < 3 * kPayloadFaultCount * 2; ++i) {
    const std::optional<MapMessage> m = NextMap(inj);
    ASSERT_TRUE(m.has_value());
    const MapDecodeResult d = DecodeMap(m->payload);
    if (m->robot_id == 99) {
      EXPECT_TRUE(d.ok());
      EXPECT_EQ(d.map.size(), 30u);
      ++made["unknown_sender"];
    } else {
      EXPECT_TRUE(m->robot_id == 1 || m->robot_id == 2);
      EXPECT_EQ(m->kind, MapKind::kGlobal);
      EXPECT_EQ(m->incarnation, kInjectPayloadIncarnation);  // no writer is bound to it: decoded
      EXPECT_FALSE(d.ok());
      ++made[std::string(ToString(d.error))];
    }
  }
  EXPECT_EQ(made.count("ok"), 0u);
  // Every decode error is among what was made, from both claimed senders in turn.
  for (int e = 1; e < kMapDecodeErrorCount; ++e)
    EXPECT_GT(made[std::string(ToString(static_cast<MapDecodeError>(e)))], 0);
  EXPECT_GT(made["unknown_sender"], 0);
  EXPECT_EQ(inj.sent().at("truncated").at(1), inj.sent().at("truncated").at(2));
  EXPECT_EQ(inj.sent().count("stale_version"), 0u);
  EXPECT_EQ(inj.sent().count("shuffled"), 0u);
}

TEST(MapInjector, StaleAndShuffledMapsFollowWhatTheRobotPublished) {
  MapInjector inj({2}, {"stale_version", "shuffled"}, 99, 5);
  EXPECT_FALSE(NextMap(inj).has_value());
  inj.OnMap(RobotMap(2, 1, 10));
  EXPECT_FALSE(NextMap(inj).has_value());  // no older version than 1 to claim
  const MapMessage v3 = RobotMap(2, 3, 10);
  inj.OnMap(v3);
  inj.OnMap(RobotMap(2, 2, 10));  // an older one arriving late changes nothing
  std::optional<MapMessage> stale = NextMap(inj);
  ASSERT_TRUE(stale.has_value());
  EXPECT_EQ(stale->version, 2u);
  EXPECT_EQ(stale->incarnation, 7u);
  EXPECT_EQ(stale->payload, v3.payload);
  // shuffled waits until an agent reports robot 2 aligned.
  EXPECT_EQ(NextMap(inj)->version, 2u);
  AgentStatus s;
  s.robot_id = 1;
  s.peers_aligned = {2};
  inj.OnStatus(s);
  // The faulty peer: its own incarnation in robot 2's frame, two honest copies, then two
  // shuffled maps, then honest again.
  std::vector<MapMessage> faulty;
  while (faulty.size() < 5) {
    std::optional<MapMessage> m = NextMap(inj);
    ASSERT_TRUE(m.has_value());
    if (m->incarnation == kInjectFaultyIncarnation) faulty.push_back(*m);
  }
  for (std::size_t i = 0; i < faulty.size(); ++i) {
    EXPECT_EQ(faulty[i].robot_id, 2u);
    EXPECT_EQ(faulty[i].kind, MapKind::kLocal);
    EXPECT_EQ(faulty[i].version, i + 1);
  }
  EXPECT_EQ(faulty[0].payload, v3.payload);
  EXPECT_EQ(faulty[1].payload, v3.payload);
  EXPECT_EQ(faulty[4].payload, v3.payload);
  const LandmarkMap before = DecodeMap(v3.payload).map;
  for (const MapMessage& bad : {faulty[2], faulty[3]}) {
    const LandmarkMap after = DecodeMap(bad.payload).map;
    ASSERT_EQ(after.size(), before.size());
    int moved = 0;
    for (std::size_t i = 0; i < after.size(); ++i) {
      EXPECT_EQ(after.landmarks[i].id, before.landmarks[i].id);
      moved += (after.landmarks[i].mean - before.landmarks[i].mean).norm() > 1e-6;
    }
    EXPECT_GE(moved, 7);
  }
  EXPECT_EQ(inj.sent().at("shuffled").at(2), 2);  // the honest copies are counted apart
  EXPECT_EQ(inj.honest_sent(), 3);
  // Its own maps coming back are not taken for the robot's: the stale case still copies v3.
  for (const MapMessage& m : faulty) inj.OnMap(m);
  std::optional<MapMessage> again;
  while (!again || again->incarnation == kInjectFaultyIncarnation) again = NextMap(inj);
  EXPECT_EQ(again->version, 2u);
  EXPECT_EQ(again->payload, v3.payload);
}

TEST(MapInjector, MalformedOwnMapsAndOtherRobotsAreNotHeard) {
  MapInjector inj({2}, {"stale_version"}, 99, 5);
  MapMessage bad = RobotMap(2, 5, 10);
  bad.payload.pop_back();
  inj.OnMap(bad);
  MapMessage foreign = RobotMap(4, 5, 10);
  inj.OnMap(foreign);
  MapMessage global = RobotMap(2, 5, 10);
  global.kind = MapKind::kGlobal;
  inj.OnMap(global);
  EXPECT_FALSE(NextMap(inj).has_value());
}

// The tick flood, in turn: a robot not in the run at tick 0xFFFFFFFF with kInjectFloodSightings
// sightings (every one the claimed publisher's, of the map's tick), the robot at one of eight
// ticks below without, and the robot at the tick after its latest map's (before one is heard,
// at 0xFFFFFFFF) with them.
TEST(MapInjector, TheTickFloodTakesTurnsOfClaimedSenderAndTick) {
  MapInjector inj({2}, {"tick_flood"}, 99, 5);
  std::vector<MapMessage> made;
  for (int i = 0; i < 3; ++i) made.push_back(*NextMap(inj));
  MapMessage heard = RobotMap(2, 3, 10);
  heard.tick = 41;
  inj.OnMap(heard);
  for (int i = 0; i < 3; ++i) made.push_back(*NextMap(inj));
  const std::vector<std::pair<RobotId, std::uint32_t>> expected = {
      {99, 0xFFFFFFFFu}, {2, 0xFFFFFFFFu}, {2, 0xFFFFFFFFu}, {99, 0xFFFFFFFFu}, {2, 0xFFFFFFFEu}, {2, 42u}};
  // (the far ticks count per robot: 0xFFFFFFFF, then 0xFFFFFFFE, ...)
  std::set<std::uint32_t> versions;
  for (std::size_t k = 0; k < made.size(); ++k) {
    const MapMessage& m = made[k];
    EXPECT_EQ(m.robot_id, expected[k].first) << k;
    EXPECT_EQ(m.tick, expected[k].second) << k;
    EXPECT_EQ(m.incarnation, k >= 4 ? 7u : 1u) << k;  // the heard incarnation once heard
    versions.insert(m.version);
    ASSERT_EQ(m.sightings.size(), k % 3 == 1 ? 0u : kInjectFloodSightings) << k;
    for (const Sighting& s : m.sightings) {
      EXPECT_EQ(s.robot_id, m.robot_id);
      EXPECT_EQ(s.incarnation, m.incarnation);
      EXPECT_EQ(s.tick, m.tick);
    }
    EXPECT_TRUE(DecodeMap(m.payload).ok());
  }
  EXPECT_EQ(versions.size(), made.size());
  EXPECT_EQ(inj.sent().at("tick_flood").at(99), 2);
  EXPECT_EQ(inj.sent().at("tick_flood").at(2), 4);
}

// Robot 2's closed submap 4 of incarnation 7: landmarks 5 at (1, 2) and 6 at (3, 4).
WireSubmap ClosedSubmapOf2() {
  WireSubmap own;
  own.id = {2, 7, 4};
  own.opened_s = 10.0;
  own.closed_s = 20.0;
  own.keys = {5, 6};
  own.x = Eigen::VectorXd::Zero(7);
  own.x.tail(4) << 1.0, 2.0, 3.0, 4.0;
  EXPECT_TRUE(own.SetCovariance(0.01 * Eigen::MatrixXd::Identity(7, 7)));
  return own;
}

// forged_submaps and ghost_incarnation: nothing before the robot's closed submap and the next
// robot's map are heard; then the robot's submap under its next indices, landmarks moved 3-15
// m (forged_submaps), or under incarnations 77 and 78, the second opened at -1e9 s (ghost),
// riding on a copy of the next robot's latest local map (its version, so stale) a tick later;
// forged_relay's two ticks and versions on (a key the robot has not used yet), signed when the
// injector has a signature.
TEST(MapInjector, ForgedSubmapsRideOnAStaleCopyOfTheNextRobotsMap) {
  for (const std::string c : {"forged_submaps", "ghost_incarnation", "forged_relay"}) {
    SCOPED_TRACE(c);
    MapInjector inj({2, 3}, {c}, 99, 5);
    const bool relay = c == "forged_relay";
    if (relay) inj.SignWith([](std::span<const std::uint8_t> b) { return std::vector<std::uint8_t>{9, b[0]}; });
    const WireSubmap own = ClosedSubmapOf2();
    MapMessage from2 = RobotMap(2, 3, 10);
    from2.submaps = {EncodeSubmap(own)};
    inj.OnMap(from2);
    EXPECT_FALSE(NextMap(inj).has_value());  // robot 3's map not heard: no carrier for robot 2's
    MapMessage from3 = RobotMap(3, 8, 10);
    from3.tick = 40;
    inj.OnMap(from3);
    std::optional<MapMessage> m = NextMap(inj);
    ASSERT_TRUE(m.has_value());
    EXPECT_EQ(m->robot_id, 3u);
    EXPECT_EQ(m->version, relay ? 10u : 8u);
    EXPECT_EQ(m->tick, relay ? 42u : 41u);
    EXPECT_EQ(m->payload, from3.payload);
    std::vector<WireSubmap> rode;
    for (const SubmapBlob& blob : m->submaps) {
      SubmapDecodeResult d = DecodeSubmap(blob.bytes);
      ASSERT_TRUE(d.ok());
      rode.push_back(d.submap);
      const std::vector<std::uint8_t> signature = relay ? std::vector<std::uint8_t>{9, blob.bytes[0]}
                                                        : std::vector<std::uint8_t>{};
      EXPECT_EQ(blob.signature, signature);
    }
    if (c != "ghost_incarnation") {
      ASSERT_EQ(rode.size(), kInjectForgedSubmapCount);
      for (std::uint32_t k = 0; k < rode.size(); ++k) {
        EXPECT_EQ(rode[k].id, (SubmapId{2, 7, 5 + k}));
        for (Eigen::Index j = 3; j < 7; j += 2) {
          const double moved = std::hypot(rode[k].x(j) - own.x(j), rode[k].x(j + 1) - own.x(j + 1));
          EXPECT_GE(moved, 3.0 - 1e-4);  // (the wire's f32)
          EXPECT_LE(moved, 15.0 + 1e-4);
        }
      }
    } else {
      ASSERT_EQ(rode.size(), 2u);
      EXPECT_EQ(rode[0].id, (SubmapId{2, kInjectGhostIncarnationId, 4}));
      EXPECT_EQ(rode[0].opened_s, 10.0);
      EXPECT_EQ(rode[1].id, (SubmapId{2, kInjectGhostIncarnationId + 1, 4}));
      EXPECT_EQ(rode[1].opened_s, -1e9);
    }
  }
}

// Under robot 3's credentials (ActAs) the forgeries of robot 2 ride on a map claiming robot 3,
// the relay it is: robot 3's own maps are not heard, so the carrier is robot 2's latest under
// robot 3's id and the incarnation the latest tick lists for it, two ticks and versions on;
// nothing before a tick lists robot 3.
TEST(MapInjector, ForgedRelayUnderARobotsCredentialsClaimsThatRobot) {
  MapInjector inj({2, 4}, {"forged_relay"}, 99, 5);  // robot 3 (itself) is not among those it claims
  inj.ActAs(3);
  MapMessage from2 = RobotMap(2, 3, 10);
  from2.tick = 40;
  from2.submaps = {EncodeSubmap(ClosedSubmapOf2())};
  inj.OnMap(from2);
  EXPECT_FALSE(NextMap(inj).has_value());  // no tick yet: robot 3's incarnation unknown
  ExchangeTick t;
  t.index = 40;
  t.peers = {{2, 7, 0}, {3, 5, 0}, {4, 1, 0}};
  inj.OnTick(t);
  std::optional<MapMessage> m;
  for (int k = 0; k < 2 && !m; ++k) m = NextMap(inj);  // (robot 4's slot has nothing to forge)
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->robot_id, 3u);
  EXPECT_EQ(m->incarnation, 5u);
  EXPECT_EQ(m->version, 5u);
  EXPECT_EQ(m->tick, 42u);
  EXPECT_EQ(m->payload, from2.payload);
  ASSERT_EQ(m->submaps.size(), kInjectForgedSubmapCount);
  for (const SubmapBlob& blob : m->submaps) {
    const SubmapDecodeResult d = DecodeSubmap(blob.bytes);
    ASSERT_TRUE(d.ok());
    EXPECT_EQ(d.submap.id.robot, 2u);
  }
}

// huge_submaps: nothing before the robot's closed submap and the next robot's map are heard;
// then two valid submaps of the codec's most landmarks (2 MB each) under the robot's identity at
// new indices 1000 past its latest closed one, on forged_relay's carrier, new indices each time.
TEST(MapInjector, HugeSubmapsAreValidNewAndRideOnAKeyAgentsTake) {
  MapInjector inj({2, 3}, {"huge_submaps"}, 99, 5);
  MapMessage from2 = RobotMap(2, 3, 10);
  from2.submaps = {EncodeSubmap(ClosedSubmapOf2())};
  inj.OnMap(from2);
  EXPECT_FALSE(NextMap(inj).has_value());  // no carrier yet
  MapMessage from3 = RobotMap(3, 8, 10);
  from3.tick = 40;
  inj.OnMap(from3);
  std::set<SubmapId> seen;
  for (int turn = 0; turn < 2; ++turn) {
    std::optional<MapMessage> m = NextMap(inj);
    ASSERT_TRUE(m.has_value());
    EXPECT_EQ(m->robot_id, 3u);
    EXPECT_EQ(m->version, 10u);
    EXPECT_EQ(m->tick, 42u);
    ASSERT_EQ(m->submaps.size(), kInjectHugeSubmapCount);
    for (const SubmapBlob& blob : m->submaps) {
      EXPECT_EQ(blob.bytes.size(), SubmapPayloadBytes(kSubmapCodecMaxLandmarks));
      EXPECT_GT(blob.bytes.size(), 2000000u);
      const SubmapDecodeResult d = DecodeSubmap(blob.bytes);
      ASSERT_TRUE(d.ok());
      EXPECT_EQ(d.submap.id.robot, 2u);
      EXPECT_EQ(d.submap.id.incarnation, 7u);
      EXPECT_GE(d.submap.id.index, 4u + kInjectHugeSubmapsFrom);
      EXPECT_TRUE(seen.insert(d.submap.id).second);
      EXPECT_EQ(d.submap.opened_s, 10.0);
      EXPECT_EQ(d.submap.closed_s, 20.0);
      for (Eigen::Index j = 3; j < d.submap.x.size(); j += 2) {  // 2 m about one of own's landmarks
        const double to5 = std::hypot(d.submap.x(j) - 1.0, d.submap.x(j + 1) - 2.0);
        const double to6 = std::hypot(d.submap.x(j) - 3.0, d.submap.x(j + 1) - 4.0);
        EXPECT_LE(std::min(to5, to6), std::sqrt(8.0) + 1e-6);
      }
    }
  }
  EXPECT_EQ(inj.sent().at("huge_submaps").at(3), 2);
}

// The hostile cases: forged odometry, a far reading at the time the agent reported, a links
// table from the far future, a version jump on the robot's own map, and the huge map one turn in
// kInjectHugeEvery.
TEST(MapInjector, HostileInputFollowsWhatTheRobotsReported) {
  MapInjector inj({2}, {"odometry_stamp", "far_reading", "links_stamp", "version_jump", "huge_map"}, 99, 5);
  auto drain = [&] {
    std::vector<InjectedMessage> out;
    for (int i = 0; i < 5; ++i) {
      if (auto m = inj.Next()) out.push_back(*m);
    }
    return out;
  };
  // Nothing heard yet: only what needs no robot state, and the huge map on its first turn.
  std::vector<InjectedMessage> first = drain();
  int odom = 0, links = 0, huge = 0;
  for (const auto& m : first) {
    if (const auto* o = std::get_if<Odometry>(&m)) {
      ++odom;
      EXPECT_EQ(o->robot_id, 2u);
      EXPECT_EQ(o->stamp, 1e9);
    } else if (const auto* l = std::get_if<RadioLinks>(&m)) {
      ++links;
      EXPECT_EQ(l->stamp, 1e300);
      EXPECT_TRUE(l->links.empty());
    } else if (const auto* h = std::get_if<MapMessage>(&m)) {
      ++huge;
      EXPECT_EQ(h->incarnation, kInjectHugeIncarnation);
      EXPECT_EQ(MapPayloadCount(h->payload), kMapCodecMaxLandmarks);
      EXPECT_TRUE(DecodeMap(h->payload).ok());
    } else {
      ADD_FAILURE() << "a scan before the robot's time is known";
    }
  }
  EXPECT_GT(odom, 0);
  EXPECT_GT(links, 0);
  EXPECT_EQ(huge, 1);
  AgentStatus s;
  s.robot_id = 2;
  s.processed_until = 42.0;
  inj.OnStatus(s);
  inj.OnMap(RobotMap(2, 3, 10));
  bool scan = false, jump = false;
  for (int round = 0; round < 4; ++round) {
    for (const auto& m : drain()) {
      if (const auto* sc = std::get_if<Scan>(&m)) {
        scan = true;
        EXPECT_NEAR(sc->stamp, 42.05, 1e-9);
        ASSERT_EQ(sc->obs.size(), 1u);
        EXPECT_EQ(sc->obs[0].range, 30000.0);
      } else if (const auto* v = std::get_if<MapMessage>(&m); v && v->incarnation == 7) {
        jump = true;
        EXPECT_EQ(v->version, 0xFFFFFFF0u);
        EXPECT_EQ(v->payload, RobotMap(2, 3, 10).payload);
      }
    }
  }
  EXPECT_TRUE(scan);
  EXPECT_TRUE(jump);
  EXPECT_GT(inj.sent().at("far_reading").at(2), 0);
}

// links_ahead: once a robot's time is known, a table linking every pair of the run's robots,
// stamped kInjectLinksAheadS after it (inside the agents' plausibility window).
TEST(MapInjector, LinksAheadLinkEveryoneAheadOfTheReportedTime) {
  MapInjector inj({1, 2, 3}, {"links_ahead"}, 99, 5);
  for (int i = 0; i < 6; ++i) EXPECT_FALSE(inj.Next().has_value()) << "no robot's time is known yet";
  AgentStatus s;
  s.robot_id = 2;
  s.processed_until = 30.0;
  inj.OnStatus(s);
  std::optional<InjectedMessage> m = inj.Next();
  ASSERT_TRUE(m.has_value());
  const auto* l = std::get_if<RadioLinks>(&*m);
  ASSERT_NE(l, nullptr);
  EXPECT_EQ(l->stamp, 30.0 + kInjectLinksAheadS);
  EXPECT_EQ(l->links, (std::vector<Link>{{1, 2}, {1, 3}, {2, 3}}));
  EXPECT_EQ(inj.sent().at("links_ahead").at(2), 1);
}

}  // namespace
}  // namespace mapmesh
