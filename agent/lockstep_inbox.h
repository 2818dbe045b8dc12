#pragma once
// The lockstep inbox (D1; R3's barrier no message can stall): peers' maps, and the sightings
// riding on them, wait here from their arrival until the exchange tick after theirs applies
// them in a fixed order. The deliver phase of a tick asks it which listed peers' messages have
// not all come (Missing).
//
// What it keeps is bounded whatever arrives, and a message it refuses never holds a tick:
// - a map is taken only from a robot of the run, for a tick not applied yet (and, before this
//   incarnation's first exchange, not before the latest tick known: a late joiner gets every
//   writer's history of earlier ticks first), with at most sightings_per_map riding on it;
// - each robot has room for incarnations_per_robot incarnations. Incarnations are any numbers
//   (the launcher counts from 1, an agent started by hand takes its process id), and a
//   restarted one publishes for a tick before the tick that lists it may have arrived here, so
//   an incarnation no tick listed yet is held too; but an incarnation the latest tick lists is
//   never displaced by one it does not list (the one of those heard longest ago goes), and a
//   tick drops the maps of incarnations it does not list for it or earlier ticks. A tick waits
//   for the maps of a displaced incarnation no more (they were counted);
// - each publisher incarnation has room for room_ticks ticks of at most maps_per_tick maps each.
//   A genuine publisher needs two ticks of two maps (its local and global map of the tick not
//   applied yet, and of the next when it is ahead), whatever the ticks' indices (the feeder
//   skips the index of an exchange point a batch crosses with another). After the first exchange
//   the room keeps the nearest ticks: a map for a nearer tick displaces the farthest when the
//   room is full, so a forged tick far ahead never takes a genuine one's place; before it, the
//   latest arrivals. A map beyond maps_per_tick for a tick is counted for the barrier (up to
//   twice maps_per_tick) but not kept. So a flood under one robot's name fills that robot's
//   room only, and every other peer's stays free;
// - the barrier counts, per tick and publisher, the maps it took (a duplicate of one kept not
//   again) or counted: a map it refused for room is never waited for. A genuine publisher never
//   fills its room, so its maps are all kept. (Under one robot's name a forger can still put its
//   maps where that robot's would be, and make a tick pass before that robot's came: that is
//   why the agent refuses, before they are offered here, maps of a robot incarnation from
//   another writer than its maps were taken from; RobotWriters.)
// - a map its publisher sent for an earlier tick (the same kind, version and payload), copied
//   under a later tick, is replayed (issue R3: such a copy carried forged submaps in where the
//   radio gate had dropped the original): refused, and never counted for the barrier, so it
//   cannot make a tick pass before the publisher's own maps came; whichever came first (a copy
//   kept before its original came is taken back when it does; one taken out after its
//   original, dropped then). Only exact copies: a version below an earlier tick's with another
//   payload may be genuine after a forger's high version (the exchange refuses the stale one),
//   and refusing those would let one forged version silence a robot.
// Every refusal is counted by reason. Duplicates (a late reader gets a writer's history) are
// kept once and not counted; another map under a key held is not kept, and counted
// (key_taken): only a forger makes two maps of one key, and which one came first decides which
// is kept (the forger's, when it came before the robot's first map was taken; after that the
// agent refuses it before it gets here: RobotWriters, docs/SECURITY.md).
//
// Pure: no DDS, clocks or threads; the caller hands in the facts (the ticks' peer lists, the
// run's robots) and applies what it takes out.

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "common/types/messages.h"

namespace mapmesh {

enum class InboxRefusal : std::uint8_t {
  kPastTick = 0,      // for a tick already applied (a late copy), or before this incarnation's first (the
                      // writers' history a late joiner gets first): when these arrive depends on the
                      // host, so their count does (swarm compare leaves it out); genuine ones among them
  kFarTick,           // displaced by a nearer tick from a full room, or refused from one (the farthest)
  kUnknownRobot,      // from a robot not in the run
  kIncarnation,       // 0, or of an incarnation no tick listed for its tick, or displaced by another
  kTooManySightings,  // more sightings riding on it than a publisher makes in a tick
  kPublisherFull,     // beyond maps_per_tick for its tick and publisher: counted for the barrier, not kept
  kUnridden,          // a sighting on its own topic: in lockstep agents' sightings ride on their maps
  kReplayed,          // a copy of a map its publisher sent for an earlier tick (its kind, version, payload)
  kKeyTaken,          // another map under a map key held (tick, robot, incarnation, kind, version): the first
                      // that came is kept (a forger's, before the robot's own; or the robot's, before a forger's)
};
inline constexpr int kInboxRefusalCount = 9;

std::string_view ToString(InboxRefusal r);

struct LockstepInboxOptions {
  std::uint32_t room_ticks = 4;     // per publisher incarnation: the ticks kept (a genuine one needs two)
  std::uint32_t maps_per_tick = 4;  // kept per publisher incarnation and tick (a genuine one sends two)
  std::size_t sightings_per_map = 64;
  std::uint32_t incarnations_per_robot = 3;  // held per robot (a genuine robot needs one, two across a restart)

  // The bound on a publisher's sightings riding on one map: one sighting of each peer every
  // rendezvous period and one answer to each peer's, over span_s and one period more (the
  // agent's: the longer of a tick's period and the rendezvous window, beyond which a sighting
  // can no longer be answered; a restarted agent's replay makes that many before its first
  // tick).
  static std::size_t SightingsPerMap(std::size_t robots, double span_s, double rendezvous_period_s);
};

class LockstepInbox {
 public:
  LockstepInbox(std::vector<RobotId> robots, RobotId self, const LockstepInboxOptions& options);

  // An exchange or deliver tick as it arrives: its index is the latest known once it is the
  // highest seen. Maps of incarnations it does not list, held for it or earlier ticks, are
  // dropped (kIncarnation); before the first exchange, maps held for ticks before it too
  // (kPastTick).
  void OnTick(std::uint32_t index, const std::vector<TickPeer>& peers);

  // A peer's map with the sightings riding on it: kept (refused nullopt, also for a duplicate)
  // or refused. A rider that is not the publisher's, of the map's tick, is dropped and counted
  // in `foreign_riders` (the map is kept). `writer` (the DDS writer's GUID, empty when unknown)
  // is kept with it and handed out with it (RobotWriters: the caller judges it).
  struct Offer {
    std::optional<InboxRefusal> refused;
    std::uint32_t foreign_riders = 0;
  };
  Offer OfferMap(const MapMessage& map, const std::string& writer = {});
  // A sighting on its own topic: always refused (kUnridden), counted.
  void OfferUnridden();

  // The messages due at the exchange tick `tick` (those of earlier ticks, and untagged ones),
  // taken out: maps by (tick, robot, incarnation, kind, version), then sightings by (tick,
  // robot, incarnation, stamp, kind, other, other incarnation). Those of ticks before the first
  // tick taken at are dropped (kPastTick). From here on, maps of ticks before `tick` are past.
  struct Due {
    std::vector<MapMessage> maps;
    std::vector<std::string> writers;  // each map's writer, as offered
    std::vector<Sighting> sightings;
  };
  Due TakeBefore(std::uint32_t tick);

  // For a deliver tick: each listed peer incarnation but `self` whose maps have not all come,
  // with how many have (messages).
  std::vector<TickPeer> Missing(const ExchangeTick& tick) const;

  const std::array<std::uint32_t, kInboxRefusalCount>& refused() const { return refused_; }
  std::size_t sightings_per_map() const { return options_.sightings_per_map; }
  std::uint32_t refused_total() const;
  std::size_t maps_held() const;       // maps kept now
  std::size_t sightings_held() const;  // sightings kept now
  // The most maps it can hold: publishers (robots but self, times incarnations_per_robot) times
  // their room.
  std::size_t MaxMapsHeld() const;

 private:
  using MapKey = std::tuple<std::uint32_t, RobotId, std::uint32_t, int, std::uint32_t>;
  using SightingKey = std::tuple<std::uint32_t, RobotId, std::uint32_t, double, int, RobotId, std::uint32_t>;
  using Publisher = std::pair<RobotId, std::uint32_t>;
  struct Kept {  // a map kept, and the writer it came from
    MapMessage map;
    std::string writer;
  };
  struct Slot {                 // one publisher's messages of one tick
    std::uint32_t counted = 0;  // distinct maps taken or counted (the barrier's)
    std::map<MapKey, Kept> maps;
    std::map<SightingKey, Sighting> sightings;
  };
  struct Held {                           // one publisher incarnation's
    std::map<std::uint32_t, Slot> ticks;  // by tick
    std::deque<MapKey> arrivals;          // before any tick is known: its maps held, oldest first
    std::uint64_t last_arrival = 0;       // the arrival count at its latest map
  };
  // Drops a publisher's oldest arrival (before any tick is known).
  void DropOldest(Held& held);

  // The latest kTakenKept maps taken out of each publisher incarnation and kind: version and
  // payload digest.
  static constexpr std::size_t kTakenKept = 8;
  std::map<std::tuple<RobotId, std::uint32_t, int>, std::deque<std::pair<std::uint32_t, std::uint64_t>>> taken_;
  // Whether a map copies one its publisher sent for an earlier tick, taken out or held in
  // `held` (when given).
  bool Replayed(const MapMessage& map, const Held* held) const;
  // Whether two maps under one key are the same message (a writer's history delivers it again),
  // their riding sightings aside.
  static bool SameMap(const MapMessage& a, const MapMessage& b);

  bool Listed(RobotId robot, std::uint32_t incarnation) const { return listed_.contains({robot, incarnation}); }
  // Room for one more incarnation of `robot` (displacing one the latest tick does not list);
  // false when every one held is listed.
  bool MakeRoomForIncarnation(RobotId robot);
  void Refuse(InboxRefusal r, std::uint32_t n = 1) { refused_[static_cast<std::size_t>(r)] += n; }

  std::vector<RobotId> robots_;
  RobotId self_;
  LockstepInboxOptions options_;
  std::optional<std::uint32_t> latest_;  // the highest tick index seen
  std::optional<std::uint32_t> first_;   // the first tick taken at
  std::uint32_t applied_ = 0;            // maps of ticks before this are past
  std::set<Publisher> listed_;           // the incarnations the latest tick lists
  std::uint64_t arrivals_ = 0;           // maps taken so far
  // Displaced incarnations' counts per tick, for the barrier (the latest few).
  std::map<std::tuple<std::uint32_t, RobotId, std::uint32_t>, std::uint32_t> displaced_;
  std::map<Publisher, Held> held_;
  std::array<std::uint32_t, kInboxRefusalCount> refused_{};
};

}  // namespace mapmesh
