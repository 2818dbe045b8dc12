#pragma once
// MapInjector: the decisions of mapmesh-inject, a fault injector for experiments and tests
// (pure; the process wires it to DDS). It listens to the maps the robots of a run publish and
// to the agents' statuses, and makes bad map messages, going through the chosen cases and, for
// each case, through the run's robots as claimed senders:
//   truncated .. out_of_bounds  a payload corrupted so that decoding must refuse it (map_faults.h),
//                            sent as the sender's GLOBAL map under kInjectPayloadIncarnation;
//   stale_version            a copy of the sender's latest local map under an older version;
//   unknown_sender           a well-formed random map from a robot id that is not in the run;
//   shuffled                 a faulty peer: a further incarnation of the sender
//                            (kInjectFaultyIncarnation) whose maps are copies of the sender's
//                            latest local map, twice honest, so that agents align and confirm
//                            it, then twice with its coordinates shuffled (well-formed but
//                            wrong, so that alignment verification must refuse them and drop
//                            the alignment), and so on. It starts once
//                            some agent reports the sender aligned, and its map has at least 6
//                            landmarks.
// and hostile input the agents must refuse, each counted, without changing what they do:
//   odometry_stamp           an odometry message for the robot stamped 1e9 s (on its odom topic);
//   far_reading              a scan with one reading 30 km away, stamped just after the time the
//                            robot's agent last reported, numbered far ahead of the stream
//                            (kInjectFarReadingSeq: a glitch must not count as lost scans);
//   links_stamp              a radio-links table stamped 1e300 s that links nobody;
//   links_ahead              a radio-links table linking every pair of robots, stamped
//                            kInjectLinksAheadS after the robot's agent last reported (a stamp
//                            agents find plausible), from a writer that is not the feeder's;
//   version_jump             a copy of the robot's latest local map under version 0xFFFFFFF0;
//   huge_map                 a well-formed map of kMapCodecMaxLandmarks landmarks (1.6 MB) from
//                            a further incarnation of the robot (kInjectHugeIncarnation), one
//                            in every kInjectHugeEvery turns of the case;
//   tick_flood               lockstep's inbox flooded (issue R3), in turn: a map from a robot
//                            not in the run at tick 0xFFFFFFFF carrying kInjectFloodSightings
//                            sightings (each the claimed publisher's, of the map's tick); one
//                            from the robot at one of the eight ticks below 0xFFFFFFFF, without
//                            sightings; and one from the robot at the tick after its latest
//                            map's (a tick agents take; before one is heard, 0xFFFFFFFF) with the
//                            sightings.
//   forged_submaps           submaps under the robot's identity it never made (issue R3): copies
//                            of its latest closed submap under its next kInjectForgedSubmaps
//                            indices, landmarks moved 3-15 m, riding on a copy of the next
//                            robot's latest local map at the tick after it (so that it waits for
//                            a tick agents take, and is no genuine map's duplicate). The robot's
//                            own agent is offered submaps of its own robot, the others forgeries
//                            of a peer's;
//   ghost_incarnation        the robot's latest closed submap under incarnation
//                            kInjectGhostIncarnation (never run), and under
//                            kInjectGhostIncarnation + 1 opened at -1e9 s, on the same carrier:
//                            a chain whose time overlaps the robot's took its place in every join;
//   forged_relay             the forgeries of forged_submaps on a map key of the next robot's it
//                            has not used yet (its latest local map two versions and two ticks on,
//                            there before the robot's own: first arrival wins, and agents take it),
//                            as a relay holding that robot's credentials would send them (issue
//                            R3: under DDS Security the injector signs them with its own identity);
//   huge_submaps             valid submaps of kSubmapCodecMaxLandmarks landmarks (2 MB each) under the
//                            robot's identity at new indices from its latest closed submap's +
//                            kInjectHugeSubmapsFrom on, kInjectHugeSubmapCount per message, on
//                            forged_relay's carrier (a key agents take, so that what rides on it
//                            is read): the byte budgets of issue R3 must refuse them.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <span>
#include <string>
#include <tuple>
#include <variant>
#include <vector>

#include "common/map/landmark_map.h"
#include "common/map/submap_codec.h"
#include "common/types/messages.h"

namespace mapmesh {

inline constexpr const char* kInjectStaleVersion = "stale_version";
inline constexpr const char* kInjectUnknownSender = "unknown_sender";
inline constexpr const char* kInjectShuffled = "shuffled";
inline constexpr const char* kInjectOdometryStamp = "odometry_stamp";
inline constexpr const char* kInjectFarReading = "far_reading";
inline constexpr const char* kInjectLinksStamp = "links_stamp";
inline constexpr const char* kInjectLinksAhead = "links_ahead";
inline constexpr double kInjectLinksAheadS = 15.0;
inline constexpr const char* kInjectVersionJump = "version_jump";
inline constexpr const char* kInjectHugeMap = "huge_map";
inline constexpr std::uint32_t kInjectHugeIncarnation = 3000000001u;
inline constexpr int kInjectHugeEvery = 10;
inline constexpr const char* kInjectTickFlood = "tick_flood";
inline constexpr std::size_t kInjectFloodSightings = 1000;
inline constexpr const char* kInjectForgedSubmaps = "forged_submaps";
inline constexpr std::uint32_t kInjectForgedSubmapCount = 5;
inline constexpr const char* kInjectGhostIncarnation = "ghost_incarnation";
inline constexpr std::uint32_t kInjectGhostIncarnationId = 77;
inline constexpr const char* kInjectForgedRelay = "forged_relay";
inline constexpr const char* kInjectHugeSubmaps = "huge_submaps";
inline constexpr std::uint32_t kInjectHugeSubmapCount = 2;
inline constexpr std::uint32_t kInjectHugeSubmapsFrom = 1000;
inline constexpr std::uint32_t kInjectFarReadingSeq = 999999u;
// The incarnation the faulty peer of the shuffled case claims (real agents count from 1).
inline constexpr std::uint32_t kInjectFaultyIncarnation = 3000000000u;
// The incarnation the corrupted payloads claim: one no real agent runs, so that no writer is
// bound to it and they reach the decoder (under a robot's own incarnation another writer's map
// is refused unread: agent/robot_writers.h). In lockstep no tick lists it: the inbox drops them.
inline constexpr std::uint32_t kInjectPayloadIncarnation = 3000000002u;

// One injected message: a map, or forged sensor data or links.
using InjectedMessage = std::variant<MapMessage, Odometry, Scan, RadioLinks>;

// Every case, in the order they are sent.
std::vector<std::string> AllInjectCases();
// "all" or a comma-separated list of cases (repeats ignored); nullopt on an unknown or no case.
std::optional<std::vector<std::string>> ParseInjectCases(const std::string& text);

class MapInjector {
 public:
  // robots: the run's robot ids (the claimed senders); unknown_id must not be one of them.
  MapInjector(std::vector<RobotId> robots, std::vector<std::string> cases, RobotId unknown_id, std::uint64_t seed);

  // A map seen on the map topic (the injector's own messages included; they are ignored).
  void OnMap(const MapMessage& m);
  void OnStatus(const AgentStatus& s);
  // A lockstep tick: the incarnations it lists (what a carrier of a robot not heard claims).
  void OnTick(const ExchangeTick& t);
  // Under robot N's credentials (--inject-identity agentN): forged_relay and huge_submaps ride
  // on a map claiming N, the relay it is (issue R3: the secure forgery from a real agent's
  // credentials). N's own maps may not reach it (a participant of N's identity is not matched
  // with N's), so that carrier is the forged robot's latest map under N's id and the
  // incarnation the latest tick lists for N, two ticks and versions on.
  void ActAs(RobotId robot) { act_as_ = robot; }
  // Secure runs: the forged submaps go out signed with the injector's own identity (a robot's
  // real key makes a signature its peers can check, and refuse as not the claimed robot's).
  void SignWith(std::function<std::vector<std::uint8_t>(std::span<const std::uint8_t>)> sign) {
    sign_ = std::move(sign);
  }

  // The next message that can be made now, trying every (case, sender) slot once in turn,
  // or nothing when no case is ready.
  std::optional<InjectedMessage> Next();

  // Messages made so far: case -> claimed sender -> count (shuffled: the shuffled maps only).
  const std::map<std::string, std::map<RobotId, int>>& sent() const { return sent_; }
  // Honest maps the faulty peers sent before turning bad.
  int honest_sent() const { return honest_sent_; }
  // Per robot: its local maps heard, and whether one of its closed submaps was (what the
  // submap cases need before they can send).
  struct HeardFrom {
    int maps = 0;
    bool closed_submap = false;
  };
  std::map<RobotId, HeardFrom> heard_from() const;
  RobotId unknown_id() const { return unknown_id_; }
  const std::vector<std::string>& cases() const { return cases_; }

 private:
  using MsgKey = std::tuple<RobotId, std::uint32_t, std::uint32_t>;  // robot, incarnation, version
  struct Heard {
    MapMessage msg;
    LandmarkMap map;
  };
  static MsgKey Key(const MapMessage& m) { return {m.robot_id, m.incarnation, m.version}; }
  // The faulty peer's maps 1, 2, 5, 6, 9, 10, ... are honest copies.
  static bool IsHonest(const MapMessage& m) {
    return m.incarnation == kInjectFaultyIncarnation && m.version % 4 != 3 && m.version % 4 != 0;
  }
  std::optional<InjectedMessage> Make(const std::string& c, RobotId sender);
  std::optional<InjectedMessage> MakeHostile(const std::string& c, RobotId target);
  LandmarkMap RandomMap(int n);

  std::vector<RobotId> robots_;
  std::vector<std::string> cases_;
  std::function<std::vector<std::uint8_t>(std::span<const std::uint8_t>)> sign_;
  RobotId unknown_id_;
  std::mt19937_64 rng_;
  std::map<RobotId, Heard> heard_;  // each robot's newest well-formed local map of its own
  std::map<RobotId, int> maps_heard_;
  std::set<RobotId> aligned_;  // robots some agent reported aligned
  std::set<MsgKey> injected_;
  std::map<std::string, std::map<RobotId, int>> sent_;
  std::size_t tick_ = 0;
  std::uint32_t unknown_version_ = 0;
  std::map<RobotId, std::uint32_t> faulty_version_;  // per claimed sender
  int honest_sent_ = 0;
  std::map<RobotId, double> processed_until_;  // what each robot's agent last reported
  std::vector<std::uint8_t> huge_payload_;     // made once
  std::map<RobotId, std::uint32_t> huge_version_;
  int huge_turns_ = 0;
  std::vector<std::uint8_t> flood_payload_;  // made once
  std::uint32_t flood_version_ = 0;
  std::map<RobotId, std::uint32_t> flood_far_;   // per robot: its far-ahead maps so far
  std::map<RobotId, WireSubmap> last_closed_;    // each robot's latest closed submap of its own, as heard
  std::map<RobotId, std::uint32_t> huge_index_;  // per robot: the next index huge_submaps uses
  std::optional<RobotId> act_as_;                // ActAs
  std::map<RobotId, std::uint32_t> listed_;      // the incarnation the latest tick lists, per robot
  // A valid submap of kSubmapCodecMaxLandmarks landmarks under `like`'s robot, incarnation and
  // stamps, at `index`: its landmarks spread 2 m about `like`'s (or 20 m about its origin).
  std::vector<std::uint8_t> HugeSubmap(const WireSubmap& like, std::uint32_t index);
  // A copy of the local map of the robot after `robot` in the run, at the tick after it, carrying
  // `submaps` (forged_submaps, ghost_incarnation); nothing while either is unknown.
  // The next robot's latest local map carrying `submaps` (signed with sign_, if set), under the
  // next tick: with `ahead`, two ticks and two versions on. Under ActAs, with `ahead`, the map
  // claims that robot (see ActAs).
  std::optional<InjectedMessage> Carry(RobotId robot, std::vector<std::vector<std::uint8_t>> submaps,
                                       bool ahead = false) const;
};

}  // namespace mapmesh
