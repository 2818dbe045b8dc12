#include "agent/lockstep_inbox.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace mapmesh {
namespace {

constexpr RobotId kSelf = 1;

// A publisher's versions grow with its ticks: by default, the tick's (the tick far ahead's too).
MapMessage Map(RobotId robot, std::uint32_t incarnation, std::uint32_t tick, MapKind kind = MapKind::kLocal,
               std::uint32_t version = 0) {
  MapMessage m;
  m.robot_id = robot;
  m.incarnation = incarnation;
  m.tick = tick;
  m.kind = kind;
  m.version = version != 0 ? version : tick + 1;
  m.payload = {static_cast<std::uint8_t>(robot), static_cast<std::uint8_t>(tick), static_cast<std::uint8_t>(version)};
  return m;
}

std::vector<Sighting> Riders(const MapMessage& m, std::size_t n) {
  std::vector<Sighting> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    out[i].robot_id = m.robot_id;
    out[i].incarnation = m.incarnation;
    out[i].tick = m.tick;
    out[i].stamp = static_cast<double>(i);
    out[i].other = kSelf;
  }
  return out;
}

std::vector<TickPeer> Peers(std::initializer_list<std::pair<RobotId, std::uint32_t>> peers, std::uint32_t n = 0) {
  std::vector<TickPeer> out;
  for (const auto& [r, i] : peers) out.push_back({r, i, n});
  return out;
}

LockstepInbox Inbox() {
  LockstepInboxOptions o;
  o.sightings_per_map = 8;
  return LockstepInbox({1, 2, 3, 4}, kSelf, o);
}

std::uint32_t Refused(const LockstepInbox& in, InboxRefusal r) { return in.refused()[static_cast<std::size_t>(r)]; }

// A map offered with these riders: its refusal, nullopt when kept.
std::optional<InboxRefusal> Offer(LockstepInbox& in, MapMessage m, std::vector<Sighting> riders = {}) {
  m.sightings = std::move(riders);
  return in.OfferMap(m).refused;
}

// The messages of earlier ticks come out in the fixed order (tick, robot, incarnation, kind,
// version), then their riders; later ticks' stay. The barrier counts each map once.
TEST(LockstepInbox, AppliesEarlierTicksInOrderAndCountsForTheBarrier) {
  LockstepInbox in = Inbox();
  in.OnTick(5, Peers({{1, 1}, {2, 1}, {3, 1}}));
  EXPECT_TRUE(in.TakeBefore(5).maps.empty());  // this incarnation's first exchange: tick 5
  const MapMessage a = Map(3, 1, 5, MapKind::kGlobal), b = Map(2, 1, 5), c = Map(3, 1, 5), d = Map(2, 1, 6);
  EXPECT_FALSE(Offer(in, a));
  EXPECT_FALSE(Offer(in, b, Riders(b, 2)));
  EXPECT_FALSE(Offer(in, c, Riders(c, 1)));
  EXPECT_FALSE(Offer(in, d));
  EXPECT_FALSE(Offer(in, c, Riders(c, 1)));  // again (a late reader): kept once, not counted again
  ExchangeTick deliver;
  deliver.index = 5;
  deliver.phase = TickPhase::kDeliver;
  deliver.peers = {{1, 1, 2}, {2, 1, 1}, {3, 1, 2}};
  EXPECT_TRUE(in.Missing(deliver).empty());
  deliver.peers[1].messages = 2;
  ASSERT_EQ(in.Missing(deliver).size(), 1u);
  EXPECT_EQ(in.Missing(deliver)[0], (TickPeer{2, 1, 1}));
  const LockstepInbox::Due due = in.TakeBefore(6);
  ASSERT_EQ(due.maps.size(), 3u);
  EXPECT_EQ(due.maps[0].robot_id, 2u);
  EXPECT_EQ(due.maps[1].robot_id, 3u);
  EXPECT_EQ(due.maps[1].kind, MapKind::kLocal);
  EXPECT_EQ(due.maps[2].kind, MapKind::kGlobal);
  EXPECT_TRUE(due.maps[0].sightings.empty());  // the riders come apart, after the maps
  ASSERT_EQ(due.sightings.size(), 3u);
  EXPECT_EQ(due.sightings[0].robot_id, 2u);
  EXPECT_EQ(due.sightings[2].robot_id, 3u);
  EXPECT_EQ(in.maps_held(), 1u);  // tick 6's
  EXPECT_EQ(in.refused_total(), 0u);
  // Tick 5 is applied: a copy of one of its maps is past now.
  EXPECT_EQ(Offer(in, Map(2, 1, 5, MapKind::kGlobal)), InboxRefusal::kPastTick);
}

// Each gate refuses and counts, in order, and nothing refused is held.
TEST(LockstepInbox, RefusesWhatNoPeerOfTheRunSendsAndCountsWhy) {
  LockstepInbox in = Inbox();
  EXPECT_EQ(Offer(in, Map(99, 1, 4)), InboxRefusal::kUnknownRobot);
  EXPECT_EQ(Offer(in, Map(kSelf, 1, 4)), InboxRefusal::kUnknownRobot);
  EXPECT_EQ(Offer(in, Map(2, 0, 4)), InboxRefusal::kIncarnation);
  const MapMessage many = Map(2, 1, 4);
  EXPECT_EQ(Offer(in, many, Riders(many, 9)), InboxRefusal::kTooManySightings);
  EXPECT_FALSE(Offer(in, many, Riders(many, 8)));
  // Incarnations are any numbers (an agent started by hand takes its process id): three per
  // robot are held, ticks listing them or not.
  EXPECT_FALSE(Offer(in, Map(2, 40417, 4)));
  EXPECT_FALSE(Offer(in, Map(2, 77, 4)));
  EXPECT_FALSE(Offer(in, Map(2, 40417, 5)));  // heard again: 77 is now the one heard longest ago
  EXPECT_FALSE(Offer(in, Map(2, 901, 5)));    // a fourth: 1 goes (heard longest ago)
  EXPECT_EQ(Refused(in, InboxRefusal::kIncarnation), 2u);
  in.OnTick(4, Peers({{1, 1}, {2, 40417}}));  // the tick lists 40417: 77's and 901's maps for 4 go
  EXPECT_EQ(Refused(in, InboxRefusal::kIncarnation), 3u);
  EXPECT_EQ(in.maps_held(), 3u);  // 40417's two, and 901's for tick 5 (a restart the next tick may list)
  // Listed, 40417 is never displaced: two others come and go.
  for (std::uint32_t inc : {5u, 6u, 7u, 8u}) EXPECT_FALSE(Offer(in, Map(2, inc, 5)));
  EXPECT_EQ(Refused(in, InboxRefusal::kIncarnation), 6u);
  // Before the first exchange, a tick before the latest known is history.
  EXPECT_EQ(Offer(in, Map(2, 40417, 3)), InboxRefusal::kPastTick);
  in.TakeBefore(5);  // the first exchange: 40417's map for tick 4 is from before it
  EXPECT_EQ(Offer(in, Map(2, 40417, 4, MapKind::kGlobal)), InboxRefusal::kPastTick);
  in.OfferUnridden();
  EXPECT_EQ(Refused(in, InboxRefusal::kUnknownRobot), 2u);
  EXPECT_EQ(Refused(in, InboxRefusal::kTooManySightings), 1u);
  EXPECT_EQ(Refused(in, InboxRefusal::kPastTick), 3u);
  EXPECT_EQ(Refused(in, InboxRefusal::kUnridden), 1u);
  EXPECT_EQ(in.maps_held(), 3u);  // 40417's for tick 5, and two of 5-8's
  EXPECT_LE(in.maps_held(), in.MaxMapsHeld());
}

// A restarted peer publishes for a tick before the tick listing its new incarnation arrives
// here: its maps are held, and the barrier counts them. One the tick does not list, and one
// displaced for room, never hold a tick.
TEST(LockstepInbox, ARestartedPeersFirstMapsAreHeldBeforeTheTickListsIt) {
  LockstepInbox in = Inbox();
  in.OnTick(9, Peers({{1, 1}, {2, 1}}));
  in.TakeBefore(9);
  EXPECT_FALSE(Offer(in, Map(2, 2, 10)));  // robot 2's second incarnation, before tick 10 lists it
  EXPECT_FALSE(Offer(in, Map(2, 2, 10, MapKind::kGlobal)));
  in.OnTick(10, Peers({{1, 1}, {2, 2}}));
  ExchangeTick deliver;
  deliver.index = 10;
  deliver.peers = {{1, 1, 2}, {2, 2, 2}};
  EXPECT_TRUE(in.Missing(deliver).empty());
  EXPECT_EQ(in.TakeBefore(11).maps.size(), 2u);
  // Two ghosts of robot 3 fill its room with robot 3's genuine third: the genuine goes (heard
  // longest ago), yet tick 11 does not wait for it; at the tick the ghosts go.
  EXPECT_FALSE(Offer(in, Map(3, 3, 11)));
  EXPECT_FALSE(Offer(in, Map(3, 70, 11)));
  EXPECT_FALSE(Offer(in, Map(3, 71, 11)));
  EXPECT_FALSE(Offer(in, Map(3, 72, 11)));
  in.OnTick(11, Peers({{1, 1}, {2, 2}, {3, 3}}));
  deliver.index = 11;
  deliver.peers = {{1, 1, 0}, {2, 2, 0}, {3, 3, 1}};
  EXPECT_TRUE(in.Missing(deliver).empty());
  EXPECT_EQ(in.maps_held(), 0u);
  EXPECT_EQ(Refused(in, InboxRefusal::kIncarnation), 4u);  // 3 displaced, 70-72 dropped by the tick... once each
}

// A late joiner: the writers' history of earlier ticks, then the current tick's maps, maybe
// before the first tick message. What the first tick shows to be history is dropped (past);
// the current tick's are kept, and the exchange after the first applies them.
TEST(LockstepInbox, ALateJoinerKeepsTheCurrentTicksMapsOfAllTheHistory) {
  LockstepInbox in = Inbox();
  for (std::uint32_t t = 1; t <= 30; ++t) {  // robot 2's whole history, then tick 31 (the current)
    EXPECT_FALSE(Offer(in, Map(2, 1, t, MapKind::kLocal, t)));
    EXPECT_FALSE(Offer(in, Map(2, 1, t, MapKind::kGlobal, t)));
  }
  EXPECT_FALSE(Offer(in, Map(2, 1, 31, MapKind::kLocal, 31)));
  EXPECT_FALSE(Offer(in, Map(3, 1, 0xFFFFFFF0u)));  // a forger's: robot 3's room is its own
  EXPECT_EQ(in.maps_held(), 17u);                   // robot 2's latest 16 arrivals
  EXPECT_EQ(Refused(in, InboxRefusal::kPastTick), 45u);
  in.OnTick(30, Peers({{1, 1}, {2, 1}, {3, 1}}));  // the deliver phase of tick 30 comes first
  EXPECT_EQ(in.maps_held(), 4u);                   // 30's two, 31's, and the forged one
  EXPECT_EQ(Refused(in, InboxRefusal::kPastTick), 58u);
  EXPECT_FALSE(Offer(in, Map(2, 1, 31, MapKind::kGlobal, 31)));
  in.OnTick(31, Peers({{1, 1}, {2, 1}, {3, 1}}));
  EXPECT_TRUE(in.TakeBefore(31).maps.empty());  // the first exchange: 30's are from before it
  EXPECT_EQ(Refused(in, InboxRefusal::kPastTick), 60u);
  ExchangeTick deliver;
  deliver.index = 31;
  deliver.peers = {{2, 1, 2}, {3, 1, 0}};
  EXPECT_TRUE(in.Missing(deliver).empty());
  EXPECT_EQ(in.TakeBefore(32).maps.size(), 2u);
}

// A publisher's room: room_ticks ticks of maps_per_tick maps. After the first exchange it keeps
// the nearest ticks (whatever their indices: the feeder skips some), a nearer one displacing the
// farthest; maps beyond maps_per_tick for a tick are counted for the barrier (so a tick never
// waits on them) but not kept.
TEST(LockstepInbox, APublishersRoomKeepsTheNearestTicks) {
  LockstepInbox in = Inbox();
  in.OnTick(10, Peers({{1, 1}, {2, 1}, {3, 1}}));
  in.TakeBefore(10);
  for (std::uint32_t t : {0xFFFFFFF3u, 0xFFFFFFF2u, 0xFFFFFFF1u, 0xFFFFFFF0u}) EXPECT_FALSE(Offer(in, Map(2, 1, t)));
  EXPECT_EQ(Offer(in, Map(2, 1, 0xFFFFFFF9u)), InboxRefusal::kFarTick);  // the room full, and the farthest
  EXPECT_FALSE(Offer(in, Map(2, 1, 10)));                                // displaces 0xFFFFFFF3
  EXPECT_FALSE(Offer(in, Map(2, 1, 17)));  // the next exchange, seven indices on: displaces 0xFFFFFFF2
  EXPECT_EQ(Refused(in, InboxRefusal::kFarTick), 3u);
  in.OnTick(17, Peers({{1, 1}, {2, 1}, {3, 1}}));
  EXPECT_EQ(in.TakeBefore(17).maps.size(), 1u);  // 10's
  // Four maps of one tick are kept (17's first among them); four more are counted for the
  // barrier, not kept.
  for (std::uint32_t v = 19; v <= 25; ++v) {  // (after 17's first, version 18)
    const std::optional<InboxRefusal> r = Offer(in, Map(2, 1, 17, MapKind::kLocal, v));
    if (v <= 21) {
      EXPECT_FALSE(r) << v;
    } else {
      EXPECT_EQ(r, InboxRefusal::kPublisherFull) << v;
    }
  }
  ExchangeTick deliver;
  deliver.index = 17;
  deliver.peers = {{2, 1, 7}};
  EXPECT_TRUE(in.Missing(deliver).empty());
  EXPECT_EQ(in.maps_held(), 6u);  // four of 17 and the two forged left
  EXPECT_LE(in.maps_held(), in.MaxMapsHeld());
  EXPECT_EQ(in.MaxMapsHeld(), 3u * 3u * 4u * 4u);  // robots 2-4, 3 incarnations each; 4 ticks, 4 maps
}

// Issue R3: a copy of a peer's map a tick later (its kind, version and payload) carried forged
// submaps in where the radio gate had dropped the original. A copy is refused and never counted
// for the barrier, whether it comes after its original or before it (then taken back when the
// original comes), or is taken out after it. Another payload under the same version is not a
// copy: after a forger's high version a genuine publisher's versions look old, and must still
// count (the exchange judges versions).
TEST(LockstepInbox, ACopyOfAnEarlierTicksMapIsRefusedAndNeverWaitedFor) {
  LockstepInbox in = Inbox();
  in.OnTick(5, Peers({{1, 1}, {2, 1}, {3, 1}}));
  in.TakeBefore(5);
  const MapMessage original = Map(2, 1, 5, MapKind::kLocal, 40);
  MapMessage copy = original;
  copy.tick = 6;
  ExchangeTick deliver6;
  deliver6.index = 6;
  deliver6.peers = {{2, 1, 1}};
  // The copy first: kept for now (nothing earlier known), and counted ...
  EXPECT_FALSE(Offer(in, copy));
  EXPECT_TRUE(in.Missing(deliver6).empty());
  // ... until its original comes: taken back, and tick 6 waits for robot 2's own map again.
  EXPECT_FALSE(Offer(in, original));
  EXPECT_EQ(Refused(in, InboxRefusal::kReplayed), 1u);
  EXPECT_EQ(in.Missing(deliver6).size(), 1u);
  // After its original: refused on arrival, not counted.
  EXPECT_EQ(Offer(in, copy), InboxRefusal::kReplayed);
  EXPECT_EQ(in.Missing(deliver6).size(), 1u);
  // Another payload under version 40 at tick 6: not a copy, kept and counted.
  MapMessage other = copy;
  other.payload.push_back(9);
  EXPECT_FALSE(Offer(in, other));
  EXPECT_TRUE(in.Missing(deliver6).empty());
  EXPECT_EQ(Refused(in, InboxRefusal::kReplayed), 2u);
  // Once the original is taken out, a copy for any later tick is refused too; robot 3's map of
  // the same version and payload, and robot 2's global one, are their own.
  in.OnTick(6, Peers({{1, 1}, {2, 1}, {3, 1}}));
  EXPECT_EQ(in.TakeBefore(6).maps.size(), 1u);
  copy.tick = 9;
  EXPECT_EQ(Offer(in, copy), InboxRefusal::kReplayed);
  MapMessage of3 = original;
  of3.robot_id = 3;
  of3.tick = 7;
  EXPECT_FALSE(Offer(in, of3));
  MapMessage global = original;
  global.kind = MapKind::kGlobal;
  global.tick = 7;
  EXPECT_FALSE(Offer(in, global));
  // A copy for a tick further on, kept before its original came, is taken back too.
  LockstepInbox late = Inbox();
  late.OnTick(5, Peers({{1, 1}, {2, 1}}));
  late.TakeBefore(5);
  EXPECT_FALSE(Offer(late, copy));  // tick 9
  EXPECT_FALSE(Offer(late, original));
  EXPECT_EQ(Refused(late, InboxRefusal::kReplayed), 1u);
  late.OnTick(10, Peers({{1, 1}, {2, 1}}));
  EXPECT_EQ(late.TakeBefore(10).maps.size(), 1u);
}

// Issue R3: a second, different map under a key held (tick, robot, incarnation, kind, version)
// was dropped as a duplicate, in no count. Only a forger makes one: counted (key_taken), not
// kept, not counted for the barrier; the first stays. The same message again is a duplicate.
TEST(LockstepInbox, AnotherMapUnderAKeyHeldIsCountedAndNotKept) {
  LockstepInbox in = Inbox();
  in.OnTick(5, Peers({{1, 1}, {2, 1}}));
  in.TakeBefore(5);
  const MapMessage first = Map(2, 1, 6);
  EXPECT_FALSE(Offer(in, first));
  EXPECT_FALSE(Offer(in, first));  // delivered again (a writer's history)
  for (int change = 0; change < 3; ++change) {
    MapMessage other = first;
    if (change == 0) other.payload.push_back(1);
    if (change == 1) other.submaps.push_back(std::vector<std::uint8_t>{1, 2});
    if (change == 2) other.open_submap_signature = {7};
    EXPECT_EQ(Offer(in, other), InboxRefusal::kKeyTaken) << change;
  }
  EXPECT_EQ(Refused(in, InboxRefusal::kKeyTaken), 3u);
  ExchangeTick deliver6;
  deliver6.index = 6;
  deliver6.peers = {{2, 1, 2}};
  EXPECT_EQ(in.Missing(deliver6), (std::vector<TickPeer>{{2, 1, 1}}));  // only the first counted
  in.OnTick(7, Peers({{1, 1}, {2, 1}}));
  const auto out = in.TakeBefore(7);
  ASSERT_EQ(out.maps.size(), 1u);
  EXPECT_EQ(out.maps[0].payload, first.payload);
  EXPECT_TRUE(out.maps[0].submaps.empty());
}

// Over seeded streams: three genuine peers publish two maps a tick (with riders), in a random
// order of arrival that a tick never crosses, while a forger floods under robot 4's name (any
// incarnation, tick and riders), under robots not in the run, and under robots 2 and 3 with
// what no genuine publisher sends (incarnations no tick listed, past ticks, ticks far ahead,
// too many riders), and replays genuine maps. Robots 2's and 3's maps and riders come
// out of every tick exactly as without the forger, no tick waits (robot 4's included), and the
// inbox never holds more than its bound. (Under a real robot's name at the ticks it publishes
// for, a forger takes that robot's place: authenticated origins are R3's next item.)
TEST(LockstepInbox, GenuineTicksComeOutAsWithoutTheForgerWhateverItSends) {
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    std::mt19937_64 rng(seed);
    LockstepInboxOptions o;
    o.sightings_per_map = LockstepInboxOptions::SightingsPerMap(4, 2.0, 1.0);
    LockstepInbox clean({1, 2, 3, 4}, kSelf, o), attacked({1, 2, 3, 4}, kSelf, o);
    std::uniform_int_distribution<std::uint32_t> coin(0, 99);
    std::size_t most = 0;
    auto forged = [&](std::uint32_t tick) {
      const std::uint32_t who = coin(rng) % 4;
      const RobotId robot = who == 0 ? 4u : who == 1 ? 2u + coin(rng) % 2 : 5u + coin(rng) % 95;
      std::uint32_t inc = coin(rng) < 70 ? 1u : coin(rng);
      std::uint32_t t = tick + coin(rng) % 5;
      if (coin(rng) < 20) t = 0xFFFFFFFFu - coin(rng);
      if (coin(rng) < 10 && tick > 1) t = tick - 1;
      std::size_t riders = coin(rng) < 10 ? 100000 : coin(rng) % 4;
      if (robot == 2 || robot == 3) {  // only what no genuine publisher sends
        switch (coin(rng) % 4) {
          case 0: inc = 3 + coin(rng); break;                 // 2 would be plausible: a restart
          case 1: t = 0x80000000u + coin(rng) * 1000; break;  // never reached
          case 2: t = tick > 1 ? tick - 1 : 0x80000000u; break;
          default: riders = o.sightings_per_map + 1 + coin(rng); break;
        }
      }
      MapMessage f = Map(robot, inc, t, coin(rng) < 50 ? MapKind::kLocal : MapKind::kGlobal, 1000 + coin(rng));
      Offer(attacked, f, Riders(f, riders));
    };
    // The exchange at `tick` applies the ticks before: robots 2's and 3's come out as without
    // the forger.
    auto exchange = [&](std::uint32_t tick) {
      const LockstepInbox::Due a = clean.TakeBefore(tick), b = attacked.TakeBefore(tick);
      auto of_2_and_3 = [](const LockstepInbox::Due& d) {
        std::vector<MapMessage> maps;
        for (const MapMessage& m : d.maps) {
          if ((m.robot_id == 2 || m.robot_id == 3) && m.incarnation == 1) maps.push_back(m);
        }
        std::vector<Sighting> sightings;
        for (const Sighting& s : d.sightings) {
          if ((s.robot_id == 2 || s.robot_id == 3) && s.incarnation == 1) sightings.push_back(s);
        }
        return std::pair{maps, sightings};
      };
      const auto [ma, sa] = of_2_and_3(a);
      const auto [mb, sb] = of_2_and_3(b);
      ASSERT_EQ(ma.size(), mb.size()) << "seed " << seed << " tick " << tick;
      if (tick > 1) {
        ASSERT_EQ(ma.size(), 4u);
      }
      for (std::size_t i = 0; i < ma.size(); ++i) {
        EXPECT_EQ(mb[i].robot_id, ma[i].robot_id);
        EXPECT_EQ(mb[i].kind, ma[i].kind);
        EXPECT_EQ(mb[i].version, ma[i].version);
        EXPECT_EQ(mb[i].payload, ma[i].payload);
      }
      ASSERT_EQ(sa.size(), sb.size());
      for (std::size_t i = 0; i < sa.size(); ++i) EXPECT_EQ(sb[i].stamp, sa[i].stamp);
    };
    for (std::uint32_t tick = 1; tick <= 30; ++tick) {
      const std::vector<TickPeer> peers = Peers({{1, 1}, {2, 1}, {3, 1}, {4, 1}}, 2);
      clean.OnTick(tick, peers);
      attacked.OnTick(tick, peers);
      exchange(tick);
      std::vector<std::pair<MapMessage, std::vector<Sighting>>> genuine;
      for (RobotId r : {2u, 3u, 4u}) {
        const MapMessage local = Map(r, 1, tick, MapKind::kLocal, tick);
        const MapMessage global = Map(r, 1, tick, MapKind::kGlobal, tick);
        genuine.push_back({local, Riders(local, coin(rng) % 4)});
        genuine.push_back({global, {}});
      }
      std::shuffle(genuine.begin(), genuine.end(), rng);
      for (const auto& [m, riders] : genuine) ASSERT_FALSE(Offer(clean, m, riders));
      for (const auto& [m, riders] : genuine) {
        for (std::uint32_t k = coin(rng) % 40; k > 0; --k) forged(tick);
        const std::optional<InboxRefusal> r = Offer(attacked, m, riders);
        if (m.robot_id != 4) {
          ASSERT_FALSE(r) << "seed " << seed << " tick " << tick << " robot " << m.robot_id;
        }
        if (coin(rng) < 30) Offer(attacked, m, riders);  // replayed
        most = std::max(most, attacked.maps_held());
      }
      ExchangeTick deliver;
      deliver.index = tick;
      deliver.phase = TickPhase::kDeliver;
      deliver.peers = peers;
      ASSERT_TRUE(attacked.Missing(deliver).empty()) << "seed " << seed << " tick " << tick;
    }
    exchange(31);
    EXPECT_LE(most, attacked.MaxMapsHeld());
    EXPECT_GT(attacked.refused_total(), 0u);
  }
}

}  // namespace
}  // namespace mapmesh
