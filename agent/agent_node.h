#pragma once
// AgentNode holds every decision an agent makes. It is pure: time arrives inside the
// messages, randomness is seeded from the scenario, and everything leaves through an
// AgentOutput, so the same logic runs over DDS (agent_main.cc) and over an in-memory bus.

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string_view>
#include <tuple>
#include <vector>

#include "agent/delay_line.h"
#include "agent/lockstep_inbox.h"
#include "agent/map_exchange.h"
#include "agent/radio_gate.h"
#include "agent/rendezvous_tracker.h"
#include "agent/robot_writers.h"
#include "agent/sensor_sync.h"
#include "agent/submap_relay.h"
#include "common/geometry/pose_track.h"
#include "common/io/checkpoint.h"
#include "common/map/landmark_map.h"
#include "common/map/map_codec.h"
#include "common/map/map_limits.h"
#include "common/map/submap_origin.h"
#include "common/options/agent_options.h"
#include "common/slam/local_mapper.h"
#include "common/types/messages.h"

namespace mapmesh {

// Where an agent's messages go.
class AgentOutput {
 public:
  virtual ~AgentOutput() = default;
  virtual void PublishMap(const MapMessage& msg) = 0;
  virtual void PublishStatus(const AgentStatus& status) = 0;
  // Robot sightings and answers (rendezvous_tracker.h); outputs that do not carry them drop them.
  virtual void PublishSighting(const Sighting& /*sighting*/) {}
};

// What an agent knows of its run besides its own options (agent/agent_setup.h derives it from
// a scenario).
struct AgentRun {
  std::vector<RobotId> robots;  // the robots of this run; maps from others are rejected
  std::uint64_t seed = 1;       // the run's seed (the agent's generators derive theirs from it)
  double end_s = std::numeric_limits<double>::infinity();  // no stamp of the run comes after this plus
                                                           // max_stamp_jump_s (infinite: a dataset replayed whole)
  double trajectory_period_s = 0.5;    // how often the estimated pose is recorded (feeder.truth_period_s)
  double loss_probability = 0.0;       // radio.loss_probability
  double bandwidth_bytes_per_s = 0.0;  // radio.bandwidth_bytes_per_s (0: unlimited)
  double latency_s = 0.0;              // radio.latency_s
  double latency_jitter_s = 0.0;       // radio.latency_jitter_s
  FilterNoise noise;                   // the robot's motion model and its odometry and sensor noise
  SensorSpec sensor;                   // its sensor's range, noise and signatures
  bool exchange_ticks = false;         // feeder.pace lockstep: peers' messages are exchanged at ticks (ExchangeTick)
};

// The local estimator the options ask for, for a robot with this noise and sensor.
std::unique_ptr<LocalMapper> MakeLocalMapper(const AgentOptions& options, const FilterNoise& noise,
                                             const SensorSpec& sensor);

// Bytes a map message occupies on the wire: its payload plus the fixed fields.
std::size_t WireBytes(const MapMessage& msg);

// Why a well-formed map from a robot of this run was refused before it was used; each refusal
// changes nothing.
enum class MapRefusal {
  kImplausibleStamp = 0,  // its stamp is not finite or runs ahead of ours (agent.max_stamp_jump_s)
  kTooManyLandmarks,      // agent.max_peer_landmarks (refused before decoding)
  kOutOfWorld,            // a landmark beyond agent.world_radius_m
  kCovarianceTooLarge,    // a landmark less certain than agent.max_landmark_sigma_m
  kCovarianceTooSmall,    // ... or more certain than agent.min_landmark_sigma_m (issue R3)
  kVersionJump,           // a version further ahead than the peer could have published
  kTooManyIncarnations,   // a new map frame of a robot that has max_incarnations kept already
  kOtherWriter,           // from a DDS writer other than the one a map of that robot incarnation was taken from
                          // (issue R3: someone writing as the robot; RobotWriters)
};
inline constexpr int kMapRefusalCount = 8;
std::string_view ToString(MapRefusal r);

// Why a well-formed submap riding on a peer's local map (closed, or with fusion joining open)
// was refused (issue J1); each refusal changes nothing.
enum class SubmapRefusal {
  kTooManyOnOneMap = 0,  // beyond kMaxSubmapsPerMap on one map (the rest of them)
  kUnknownRobot,         // made by a robot not of this run
  kImplausibleStamp,     // opened before the run (scenario time 0), or closed after what we have received
                         // (agent.max_stamp_jump_s)
  kTooManyLandmarks,     // the map limits, as for maps
  kOutOfWorld,
  kCovarianceTooLarge,
  kCovarianceTooSmall,
  kNotThePublishers,  // an open submap that is not the publisher's own incarnation's
  // A local map's chain placements (fusion joining), all of them: one of a robot not of this
  // run or of the publisher's own chain, not finite or beyond a map's bound, or more of them
  // than the robots' chains the publisher could hold.
  kImplausiblePlacements,
  kOpenRelayedByItsRobot,  // a relayed open submap of the publisher's own robot (it sends its own as open_submap)
  kOwnRobot,               // a submap of the agent's own robot, from anyone else (issue R3)
  kOnRefusedMap,           // riding on a map the agent did not take (refused, stale, beyond the limits)
  // Secure runs (a SubmapOrigin set; issue R3): no signature, ...
  kUnsigned,
  kUnknownSigner,    // ... no certificate of the run's for the robot it claims, ...
  kForgedSignature,  // ... or a signature that is not that robot's over its bytes
  kTooLarge,         // longer than agent.max_submap_bytes (refused unread; issue R3)
};
inline constexpr int kSubmapRefusalCount = 16;
std::string_view ToString(SubmapRefusal r);
// A local map carries at most this many closed submaps, and as many relayed open ones (the first
// are taken, the rest refused).
inline constexpr std::size_t kMaxSubmapsPerMap = 1024;
// AgentNode::MaxSampleBytes: no bound below this (a scan or a small run's table must never meet
// it), and room above the sum for CDR's alignment and headers.
inline constexpr std::size_t kMinSampleBytes = 1u << 20;
inline constexpr std::size_t kSampleSlackBytes = 64u << 10;

// Counters of the maps the agent sent, received, dropped or rejected, and why.
struct AgentStats {
  std::uint32_t maps_sent = 0;
  std::uint64_t bytes_sent = 0;
  std::uint32_t maps_received = 0;   // passed the radio gate and decoded
  std::uint64_t bytes_received = 0;  // of messages that passed the radio gate
  std::uint32_t maps_out_of_range = 0;
  std::uint32_t maps_lost = 0;            // dropped by the radio loss model
  std::uint32_t maps_over_bandwidth = 0;  // arrived while the link was still busy
  std::uint32_t maps_unknown_sender = 0;
  std::array<std::uint32_t, kMapDecodeErrorCount> maps_rejected{};  // by MapDecodeError
  std::uint32_t maps_stale_version = 0;                        // not newer than one already received from that sender
  std::array<std::uint32_t, kMapRefusalCount> maps_refused{};  // by MapRefusal
  std::uint32_t maps_encode_failed = 0;                        // own maps that could not be encoded (never sent) ...
  MapDecodeError last_encode_error = MapDecodeError::kOk;      // ... the last time, why
  std::uint32_t maps_encode_trimmed = 0;      // own maps sent without landmarks beyond the codec's bound
  std::uint32_t maps_beyond_sample_size = 0;  // own maps longer than MaxSampleBytes (the transport drops them)
  std::uint32_t links_refused = 0;            // link tables with implausible stamps
  std::uint64_t landmarks_sent = 0;           // over all maps sent
  std::uint64_t payload_bytes_sent = 0;       // their encoded payloads
  std::uint64_t open_submap_bytes_sent = 0;   // the own open submaps riding on them (fusion joining)
  std::map<RobotId, std::uint32_t> maps_received_from;
  // per robot: the latest stamp of a map taken from it, or end of an open submap of it taken
  // (its publisher's or relayed): its data up to then
  std::map<RobotId, double> data_until;
  std::uint32_t sightings_sent = 0;         // robot sightings and answers published (rendezvous)
  std::uint32_t sightings_unsent = 0;       // lockstep: ... dropped: neither map of the tick could carry them, or the
                                            // oldest beyond what a peer takes on one map
  std::uint64_t sighting_bytes_sent = 0;    // ... their bytes on the wire
  std::uint32_t sightings_received = 0;     // peers' sightings and answers that passed the radio gate
  std::uint32_t sightings_gated = 0;        // ... that it dropped (out of range, lost, busy)
  std::uint32_t sightings_implausible = 0;  // ... refused before it: unknown sender or a stamp ahead of ours
  std::uint32_t sightings_delayed = 0;      // ... held in the delay line after the gate (radio.latency_s)
  // Maps the gate passed that the link's latency or transmission time held in the delay line
  // (each taken once it arrived, unless the run ended first: in_flight), and those it had no
  // room for (dropped; sightings too).
  std::uint32_t maps_delayed = 0;
  std::uint32_t maps_delay_overflow = 0;
  std::uint32_t in_flight = 0;                                            // messages in the delay line now
  std::array<std::uint32_t, kSubmapDecodeErrorCount> submaps_rejected{};  // peers' submaps, by SubmapDecodeError
  std::array<std::uint32_t, kSubmapRefusalCount> submaps_refused{};       // by SubmapRefusal
  std::uint32_t submaps_unsendable = 0;  // own closed submaps that cannot go on the wire (never sent)
  std::uint32_t MapsRejected() const;
  // Encoded bytes per landmark sent (header included), 0 before anything was sent.
  double BytesPerLandmark() const;
  std::uint32_t MapsRefused() const;
  // Everything that did not make it into peer_maps(), whatever the reason.
  std::uint32_t MapsDropped() const;
};

class AgentNode : private SensorSync::Sink {
 public:
  AgentNode(const AgentOptions& options, const AgentRun& run, RobotId self, std::uint32_t incarnation,
            AgentOutput& out);

  // The largest sample, serialised, that an agent of these options sends or takes in this run
  // (issue R3): a map message at the peers' limits (a payload of agent.max_peer_landmarks, the
  // chains held, a publication's submap budget with one submap beyond it for the closed ones and
  // again for the silent robots' open ones, its own open submap, signatures, placements and the
  // sightings a peer's inbox takes), or an exchange tick with every pair linked; at least
  // kMinSampleBytes, and kSampleSlackBytes more. agent_main gives it to Cyclone (MaxSampleSize),
  // which drops a larger sample unread, on either side, with a warning.
  static std::size_t MaxSampleBytes(const AgentOptions& options, const AgentRun& run);

  void OnOdometry(const Odometry& odom);
  void OnScan(const Scan& scan);
  void OnLinks(const RadioLinks& links);
  // A peer's map (and the sightings riding on it: each must be the map publisher's, of the
  // map's tick, else it is refused as implausible). `writer`: the GUID of the DDS writer it
  // came from (empty: unknown); once a map of a robot incarnation is taken, one from another
  // writer is refused (RobotWriters, MapRefusal::kOtherWriter), on arrival and when applied.
  void OnMap(const MapMessage& msg, const std::string& writer = {});
  // A peer's robot sighting or answer (rendezvous): through the radio gate to the tracker.
  void OnSighting(const Sighting& msg);
  // A peer's map writer came back (alive) or went away (liveliness lost or disposed).
  // Returns false, and does nothing, for the agent itself and robots not in the scenario, and
  // in lockstep (exchange_ticks: the ticks say who is alive).
  bool OnPeerLiveliness(RobotId robot, bool alive);
  // Lockstep (exchange_ticks): peers' maps and sightings wait in an inbox from their arrival;
  // this agent's own go out only at ticks. An exchange tick that lists this incarnation applies
  // the inbox's messages of earlier ticks (of this incarnation's ticks; untagged ones too) in a
  // fixed order (tick, robot, incarnation, kind, version; then the sightings), makes the listed
  // incarnations the live ones, updates the exchange and publishes the maps tagged, the held
  // sightings and answers riding on them; the gates use the tick's link table. A deliver tick checks that the inbox holds
  // every message the tick lists: it returns false while one has not arrived (the caller tries
  // again as messages come in). A tick carried out, or not for this incarnation, returns true;
  // outside lockstep, every tick does.
  bool OnTick(const ExchangeTick& tick);
  // Lockstep: for a deliver tick, each listed peer incarnation whose messages have not all
  // arrived, with how many it sent and how many are here (messages).
  std::vector<TickPeer> Missing(const ExchangeTick& tick) const;
  // Lockstep: a tick crossed a checkpoint period (agent.checkpoint_period_s) since the last
  // time this returned true.
  bool TakeCheckpointDue();
  // Re-merges what earlier incarnations of this agent knew (from its checkpoint), and holds the
  // closed submaps it held again (robots not in this run's are refused and counted). The
  // checkpoint must be this robot's, from other incarnations than this one, with valid
  // submaps: io::LoadCheckpoint refuses any other, so a violation is a programming error
  // (checked).
  // In a secure run (a SubmapOrigin set), a submap whose signature is not its robot's is
  // refused and counted, as from a peer: an edited checkpoint cannot smuggle one in.
  void Resume(const AgentCheckpoint& checkpoint);
  // Secure runs (issue R3): who signs this agent's submaps and vouches for its peers'
  // (common/map/submap_origin.h); set before the first message and Resume, outliving the node.
  // Without one (plain runs) submaps go unsigned and are taken on their map's word.
  void SetSubmapOrigin(SubmapOrigin* origin) { origin_ = origin; }
  // What to save: this incarnation's maps and the earlier ones not yet re-merged, at most
  // io::CheckpointLimits::max_earlier of them (the newest), so that the file always loads; how
  // many older ones were left out goes to *left_out. And the closed submaps held, at most
  // io::CheckpointLimits::max_submaps (the own robot's first, then by identity); how many were
  // left out goes to *submaps_left_out.
  AgentCheckpoint Checkpoint(std::size_t* left_out = nullptr, std::size_t* submaps_left_out = nullptr) const;

  RobotId id() const { return self_; }
  AgentStatus Status() const;
  LandmarkMap LocalMap() const { return mapper_->Map(); }
  Pose2 Pose() const { return mapper_->pose(); }
  const LocalMapper& mapper() const { return *mapper_; }
  double processed_until() const { return sync_.processed_until(); }
  // Scenario time at which the local map frame was fixed (the robot's pose then is its origin);
  // nullopt before the first odometry.
  std::optional<double> frame_origin_stamp() const { return sync_.frame_origin_stamp(); }
  const AgentStats& stats() const { return stats_; }
  SyncStats sync_stats() const { return sync_.stats(); }
  // The estimated pose every trajectory period (feeder.truth_period_s) of the current session.
  using PoseStamp = mapmesh::PoseStamp;
  const std::vector<PoseStamp>& trajectory() const { return trajectory_; }
  const MapExchange& exchange() const { return exchange_; }
  // The closed submaps held (own and peers') and what was sent of them (issue J1).
  const SubmapRelay& submaps() const { return submaps_; }
  // Fusion joining: each peer incarnation's chain placements, from its latest local map.
  const std::map<PeerKey, std::vector<ChainPlacement>>& peers_placements() const { return peers_placements_; }
  const RendezvousStats& rendezvous_stats() const { return rendezvous_.stats(); }
  // Lockstep: what the inbox refused, by InboxRefusal.
  const std::array<std::uint32_t, kInboxRefusalCount>& inbox_refused() const { return inbox_.refused(); }
  const GlobalMap& global() const { return exchange_.global(); }
  std::uint32_t incarnation() const { return incarnation_; }

 private:
  // SensorSync::Sink: the robot's data in time order.
  void Move(const OdometryControl& u, double dt) override;
  void ApplyScan(const Scan& scan, double stamp) override;
  bool Mapped() const override;
  void IntervalDone(const Odometry& odom) override;
  void AfterInterval(const Odometry& odom);
  // Updates the exchange and publishes both maps, tagged with the exchange tick (0: none).
  // Updates the exchange and publishes both maps, tagged with `tick` (0: realtime); `riders`
  // (lockstep: the tick's sightings and answers) go out on the first map that does.
  void PublishMaps(std::uint32_t tick, std::vector<Sighting> riders = {});
  // Publishes one map; true when it went out (with the riders, which it then takes).
  bool Publish(MapKind kind, const LandmarkMap& map, std::uint32_t version, std::uint32_t tick,
               std::vector<Sighting>& riders);
  // A peer's map or sighting through the gates into the exchange (at once, or at a tick), or,
  // when the link's latency has it arrive later, into the delay line.
  void ProcessMap(const MapMessage& msg, const std::string& writer);
  // A map that passed the gates and has arrived over the link, into the exchange.
  void ApplyMap(const MapMessage& msg);
  // Counts a peer's map refused, and (RefuseRiders) the submaps riding on one refused.
  void RefuseMap(MapRefusal r);
  void RefuseRiders(const MapMessage& msg);
  // The delay line's messages that have arrived by RadioNow(), in order.
  void TakeArrived();
  // The radio's clock for arrivals: the exchange tick's stamp in lockstep, else Clock().
  double RadioNow() const { return exchange_ticks_ ? tick_stamp_ : Clock(); }
  // The submaps and advertisement riding on a peer's local map that passed the gate, at `now`.
  void ProcessSubmaps(const MapMessage& msg, double now);
  // Own submaps closed since the last call into the relay's book.
  void TakeOwnSubmaps();
  void ProcessSighting(const Sighting& msg);
  void ApplySighting(const Sighting& msg);
  // The exchange phase of a tick, its link table present (OnTick).
  void Exchange(const ExchangeTick& tick);
  // The inbox's messages of ticks before `tick`, in order, into the exchange; the rest stay.
  void ApplyInbox(std::uint32_t tick);
  // Whether the robot is one of this run's.
  bool InRun(RobotId robot) const;
  // Whether a local map's chain placements may be taken (SubmapRefusal::kImplausiblePlacements):
  // at most MaxPlacements, in (robot, incarnation) order, each a PlausiblePlacement.
  bool PlausiblePlacements(const MapMessage& msg) const;
  // One placement: of a robot of the run, not of the publisher's own chain, finite and within a
  // map's bound.
  bool PlausiblePlacement(const ChainPlacement& c, RobotId publisher, std::uint32_t incarnation) const;
  std::size_t MaxPlacements() const;  // the run's robots times the incarnations kept of each
  std::size_t max_sample_bytes_ = 0;  // MaxSampleBytes
  // The scenario time as far as this agent can tell: its own progress, or the link table's
  // when that is ahead (before the first odometry of a restarted agent).
  double Clock() const;

  AgentOptions options_;
  std::vector<RobotId> robot_ids_;  // the robots of this run; maps from others are rejected
  RobotId self_;
  std::uint32_t incarnation_;
  AgentOutput& out_;
  RadioGate gate_;
  SensorSync sync_;
  std::unique_ptr<LocalMapper> mapper_;
  double next_map_publish_s_ = 0.0;
  double trajectory_period_s_ = 0.5;
  double next_trajectory_s_ = 0.0;
  std::vector<PoseStamp> trajectory_;
  double next_status_s_ = 0.0;
  std::uint32_t local_version_ = 0, global_version_ = 0;
  AgentStats stats_;
  MapExchange exchange_;
  RadioGate sighting_gate_;  // the radio gate for sightings: its own loss draws, so maps see the same ones
  DelayLine delay_;          // messages the gates passed, until they arrive over their link
  RendezvousTracker rendezvous_;
  SubmapRelay submaps_;
  SubmapOrigin* origin_ = nullptr;  // secure runs: signs own submaps, checks the peers'
  // Whether a submap's signature is its robot's (always, without an origin); counts a refusal.
  bool Authentic(const WireSubmap& s, std::span<const std::uint8_t> bytes, std::span<const std::uint8_t> signature);
  std::vector<std::uint8_t> SignOwn(std::span<const std::uint8_t> bytes) const;
  std::size_t own_submaps_taken_ = 0;   // the mapper's closed submaps taken into submaps_
  bool joining_ = false;                // agent.fusion joining: the back-end joins submap chains
  std::optional<WireSubmap> own_open_;  // joining: the open submap at the last publication
  // The robot incarnations heard themselves: the agent's own (this one and its checkpoint's),
  // those its ticks listed, the publishers of the maps it took. Only these supersede a chain.
  std::set<std::pair<RobotId, std::uint32_t>> heard_;
  RobotWriters writers_;  // which writer speaks for each robot incarnation
  // joining: each peer incarnation's chain placements from its latest local map (a later version
  // replaces them), and that map's version
  std::map<PeerKey, std::vector<ChainPlacement>> peers_placements_;
  std::map<PeerKey, std::uint32_t> placements_version_;
  // Publishes sightings and answers (when the run aligns by rendezvous); in lockstep holds them
  // for the next tick.
  void PublishSightings(const std::vector<Sighting>& out);

  // Lockstep exchange (OnTick): peers' messages wait in the inbox (lockstep_inbox.h).
  bool exchange_ticks_ = false;
  LockstepInbox inbox_;
  std::vector<Sighting> held_sightings_;     // own sightings and answers, to go out at the next tick
  std::optional<std::uint32_t> first_tick_;  // the first exchange tick of this incarnation
  std::uint32_t tick_done_ = 0, tick_published_ = 0, tick_delivered_ = 0;
  double tick_stamp_ = 0.0;          // the stamp of the exchange tick being applied
  bool continuity_checked_ = false;  // earlier incarnations that share this frame placed (PublishMaps)
  double next_checkpoint_s_ = 0.0;
  bool checkpoint_due_ = false;
};

}  // namespace mapmesh
