#include "agent/agent_node.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "common/check.h"
#include "common/map/map_codec.h"
#include "common/map/submap_codec.h"
#include "common/map/submap_origin.h"
#include "common/slam/dead_reckoning_mapper.h"
#include "common/slam/local_slam.h"
#include "common/slam/submap_slam.h"

namespace mapmesh {
namespace {

// MapMessage fields besides the payload: robot_id, kind, version, stamp, sequence length.
constexpr std::size_t kMapMessageFixedBytes = 4 + 1 + 4 + 4 + 8 + 8 + 4;  // keys, incarnation, version, stamps,
                                                                          // payload length
// A Sighting on the wire: ids, kind, stamp, pose, covariance, measurement and sigmas.
constexpr std::size_t kSightingWireBytes = 4 + 4 + 1 + 4 + 4 + 8 + 3 * 8 + 6 * 8 + 4 * 8;
constexpr std::size_t kChainPlacementWireBytes = 4 + 4 + 3 * 8;

// A submap closes this many landmarks short of what agent.max_submap_bytes holds: its size is
// checked before a scan, which may add a few landmarks.
constexpr std::uint32_t kSubmapCloseMargin = 16;

}  // namespace

std::unique_ptr<LocalMapper> MakeLocalMapper(const AgentOptions& options, const FilterNoise& noise,
                                             const SensorSpec& sensor) {
  if (options.slam.filter == SlamMethod::kDeadReckoning) {
    DeadReckoningOptions o = options.dead_reckoning;
    o.motion = noise.motion;
    o.sigma_range_m = sensor.sigma_range_m;
    o.sigma_bearing_rad = sensor.sigma_bearing_rad;
    return std::make_unique<DeadReckoningMapper>(o);
  }
  if (options.slam.filter == SlamMethod::kCekfSubmaps) {
    // A submap closes before it outgrows what peers take (agent.max_submap_bytes), with room
    // for the new landmarks of the scan after the check (kSubmapCloseMargin).
    LocalSlamOptions o = options.slam.ForSensor(sensor);
    const std::uint32_t within = SubmapLandmarksWithin(options.exchange.submaps.max_submap_bytes);
    const int cap = static_cast<int>(within > kSubmapCloseMargin ? within - kSubmapCloseMargin : 1);
    o.submaps.landmarks = o.submaps.landmarks > 0 ? std::min(o.submaps.landmarks, cap) : cap;
    return std::make_unique<SubmapSlam>(noise, o);
  }
  return std::make_unique<LocalSlam>(noise, options.slam.ForSensor(sensor));
}

std::size_t WireBytes(const MapMessage& msg) {
  std::size_t bytes = kMapMessageFixedBytes + msg.payload.size();
  // Submaps and the chains held (issue J1): the five sequences' lengths, 20 bytes a chain, and
  // each submap and its signature (secure runs) with their lengths.
  if (!msg.submaps_held.empty() || !msg.submaps.empty() || !msg.open_submap.empty() || !msg.open_relayed.empty()) {
    bytes += 20 + 20 * msg.submaps_held.size() + msg.open_submap.size() + msg.open_submap_signature.size();
    for (const auto& b : msg.submaps) bytes += 8 + b.bytes.size() + b.signature.size();
    for (const auto& b : msg.open_relayed) bytes += 8 + b.bytes.size() + b.signature.size();
  }
  if (!msg.own_submap_digests.empty()) bytes += 4 + 8 * msg.own_submap_digests.size();
  // The placements' length, and robot, incarnation and pose for each.
  if (!msg.placements.empty()) bytes += 4 + kChainPlacementWireBytes * msg.placements.size();
  return bytes;
}

std::string_view ToString(MapRefusal r) {
  switch (r) {
    case MapRefusal::kImplausibleStamp: return "implausible_stamp";
    case MapRefusal::kTooManyLandmarks: return "too_many_landmarks";
    case MapRefusal::kOutOfWorld: return "out_of_world";
    case MapRefusal::kCovarianceTooLarge: return "covariance_too_large";
    case MapRefusal::kCovarianceTooSmall: return "covariance_too_small";
    case MapRefusal::kVersionJump: return "version_jump";
    case MapRefusal::kTooManyIncarnations: return "too_many_incarnations";
    case MapRefusal::kOtherWriter: return "other_writer";
  }
  return "unknown";
}

std::string_view ToString(SubmapRefusal r) {
  switch (r) {
    case SubmapRefusal::kTooManyOnOneMap: return "too_many_on_one_map";
    case SubmapRefusal::kUnknownRobot: return "unknown_robot";
    case SubmapRefusal::kImplausibleStamp: return "implausible_stamp";
    case SubmapRefusal::kTooManyLandmarks: return "too_many_landmarks";
    case SubmapRefusal::kOutOfWorld: return "out_of_world";
    case SubmapRefusal::kCovarianceTooLarge: return "covariance_too_large";
    case SubmapRefusal::kCovarianceTooSmall: return "covariance_too_small";
    case SubmapRefusal::kNotThePublishers: return "not_the_publishers";
    case SubmapRefusal::kImplausiblePlacements: return "implausible_placements";
    case SubmapRefusal::kOpenRelayedByItsRobot: return "open_relayed_by_its_robot";
    case SubmapRefusal::kOwnRobot: return "own_robot";
    case SubmapRefusal::kOnRefusedMap: return "on_refused_map";
    case SubmapRefusal::kUnsigned: return "unsigned";
    case SubmapRefusal::kUnknownSigner: return "unknown_signer";
    case SubmapRefusal::kForgedSignature: return "forged_signature";
    case SubmapRefusal::kTooLarge: return "too_large";
  }
  return "unknown";
}

std::uint32_t AgentStats::MapsRefused() const {
  std::uint32_t n = 0;
  for (auto c : maps_refused) n += c;
  return n;
}

std::uint32_t AgentStats::MapsRejected() const {
  std::uint32_t n = 0;
  for (auto c : maps_rejected) n += c;
  return n;
}

double AgentStats::BytesPerLandmark() const {
  return landmarks_sent > 0 ? static_cast<double>(payload_bytes_sent) / static_cast<double>(landmarks_sent) : 0.0;
}

std::uint32_t AgentStats::MapsDropped() const {
  return maps_out_of_range + maps_lost + maps_over_bandwidth + maps_delay_overflow + maps_unknown_sender +
         maps_stale_version + MapsRejected() + MapsRefused();
}

namespace {

RadioGateOptions GateOptions(const AgentOptions& options, const AgentRun& run) {
  RadioGateOptions o;
  o.loss_probability = run.loss_probability;
  o.bandwidth_bytes_per_s = run.bandwidth_bytes_per_s;
  o.max_stamp_jump_s = options.max_stamp_jump_s;
  o.max_stamp_s = run.end_s + options.max_stamp_jump_s;
  o.latency_s = run.latency_s;
  o.latency_jitter_s = run.latency_jitter_s;
  o.link_seed = run.seed;
  return o;
}

// Arrivals this close to the radio's clock have arrived (the stamps' rounding).
constexpr double kArrivalSlackS = 1e-9;

}  // namespace

AgentNode::AgentNode(const AgentOptions& options, const AgentRun& run, RobotId self, std::uint32_t incarnation,
                     AgentOutput& out)
    : options_(options),
      robot_ids_(run.robots),
      self_(self),
      incarnation_(incarnation),
      out_(out),
      gate_(self, GateOptions(options, run), run.seed * 1000003ULL + self * 7919ULL + incarnation),
      sync_(*this, SensorSync::Options{options.sync.frame_at_first_landmark, options.max_stamp_jump_s,
                                       run.end_s + options.max_stamp_jump_s}),
      mapper_(MakeLocalMapper(options, run.noise, run.sensor)),
      trajectory_period_s_(run.trajectory_period_s),
      exchange_(self, incarnation, options.exchange, run.seed * 2654435761ULL + self * 40503ULL + incarnation),
      sighting_gate_(self, GateOptions(options, run), run.seed * 998244353ULL + self * 104729ULL + incarnation),
      rendezvous_(self, incarnation, run.robots, options.rendezvous, run.sensor.sigma_range_m,
                  run.sensor.sigma_bearing_rad),
      submaps_([&] {
        SubmapRelayOptions o = options.exchange.Submaps();
        o.max_open = run.robots.size() * static_cast<std::size_t>(options.exchange.max_incarnations);
        return o;
      }()),
      joining_(options.exchange.global.method == FusionMethod::kJoining),
      heard_{{self, incarnation}},
      exchange_ticks_(run.exchange_ticks),
      inbox_(run.robots, self,
             [&] {
               LockstepInboxOptions o;
               o.sightings_per_map = LockstepInboxOptions::SightingsPerMap(
                   run.robots.size(), std::max(options.exchange.map_publish_period_s, options.rendezvous.window_s),
                   options.rendezvous.period_s);
               return o;
             }()),
      next_checkpoint_s_(options.checkpoint_period_s) {
  max_sample_bytes_ = MaxSampleBytes(options, run);
}

std::size_t AgentNode::MaxSampleBytes(const AgentOptions& options, const AgentRun& run) {
  const SubmapRelayOptions& sub = options.exchange.submaps;
  const std::size_t robots = run.robots.size();
  // Blobs: each with its length fields and a signature; as many as the budget holds of the
  // smallest submap, and one beyond it.
  const std::size_t blobs = std::min(kMaxSubmapsPerMap, sub.send_bytes / SubmapPayloadBytes(0) + 1);
  const std::size_t blob_overhead = blobs * (8 + kMaxSubmapSignatureBytes);
  const std::size_t sightings = LockstepInboxOptions::SightingsPerMap(
      robots, std::max(options.exchange.map_publish_period_s, options.rendezvous.window_s),
      options.rendezvous.period_s);
  const std::size_t map = kMapMessageFixedBytes + kMapCodecHeaderBytes +
                          kMapCodecLandmarkBytes * options.peer_limits.max_landmarks +   // the payload
                          20 + 20 * SubmapRelay::kMaxChains +                            // the chains held
                          2 * (sub.send_bytes + sub.max_submap_bytes + blob_overhead) +  // closed, open relayed
                          sub.max_submap_bytes + kMaxSubmapSignatureBytes +              // its own open one
                          4 +
                          kChainPlacementWireBytes * robots *
                              static_cast<std::size_t>(options.exchange.max_incarnations) +
                          4 + kSightingWireBytes * sightings;
  const std::size_t tick = 64 + 8 * robots * (robots > 0 ? robots - 1 : 0) / 2 +
                           12 * robots;  // every pair linked, every peer
  return std::max({map, tick, kMinSampleBytes}) + kSampleSlackBytes;
}

void AgentNode::OnOdometry(const Odometry& odom) { sync_.OnOdometry(odom); }

void AgentNode::OnScan(const Scan& scan) { sync_.OnScan(scan); }

void AgentNode::Move(const OdometryControl& u, double dt) { mapper_->Predict(u, dt); }

void AgentNode::ApplyScan(const Scan& scan, double stamp) {
  mapper_->Observe(scan.obs, stamp);
  if (!sync_.frame_fixed() || !options_.exchange.ByRendezvous()) return;
  const Pose2 pose = mapper_->pose();
  const Eigen::Matrix3d cov = mapper_->pose_cov();
  rendezvous_.OnPose(stamp, pose, cov);
  PublishSightings(rendezvous_.OnScan(scan.obs, stamp, pose, cov));
}

void AgentNode::PublishSightings(const std::vector<Sighting>& out) {
  if (exchange_ticks_) {
    held_sightings_.insert(held_sightings_.end(), out.begin(), out.end());
    return;
  }
  for (const Sighting& s : out) {
    ++stats_.sightings_sent;
    stats_.sighting_bytes_sent += kSightingWireBytes;
    out_.PublishSighting(s);
  }
}

void AgentNode::OnSighting(const Sighting& msg) {
  if (msg.robot_id == self_ || !options_.exchange.ByRendezvous()) return;
  // In lockstep agents' sightings ride on their maps (OnMap): one on its own is no agent's.
  if (exchange_ticks_) return inbox_.OfferUnridden();
  ProcessSighting(msg);
}

void AgentNode::ProcessSighting(const Sighting& msg) {
  if (!InRun(msg.robot_id) || !std::isfinite(msg.stamp) || msg.stamp > Clock() + options_.max_stamp_jump_s) {
    ++stats_.sightings_implausible;
    return;
  }
  if (sighting_gate_.Admit(msg.robot_id, kSightingWireBytes, msg.stamp) != GateVerdict::kPass) {
    ++stats_.sightings_gated;
    return;
  }
  if (sighting_gate_.Delays()) {
    const double arrival = sighting_gate_.Arrival(msg.robot_id, kSightingWireBytes, msg.stamp);
    if (arrival > RadioNow() + kArrivalSlackS) {
      if (delay_.Hold(arrival, msg)) {
        ++stats_.sightings_delayed;
      } else {
        ++stats_.sightings_gated;  // no room: dropped as by the radio
      }
      stats_.in_flight = static_cast<std::uint32_t>(delay_.size());
      return;
    }
  }
  ApplySighting(msg);
}

void AgentNode::ApplySighting(const Sighting& msg) {
  ++stats_.sightings_received;
  rendezvous_.OnMessage(msg);
}

void AgentNode::TakeArrived() {
  if (delay_.size() == 0) return;
  for (DelayLine::Message& m : delay_.TakeArrived(RadioNow() + kArrivalSlackS)) {
    if (auto* map = std::get_if<DelayLine::HeldMap>(&m)) {
      ApplyMap(map->map);
    } else {
      ApplySighting(std::get<Sighting>(m));
    }
  }
  stats_.in_flight = static_cast<std::uint32_t>(delay_.size());
}

void AgentNode::IntervalDone(const Odometry& odom) { AfterInterval(odom); }

bool AgentNode::Mapped() const { return mapper_->size() > 0; }

void AgentNode::AfterInterval(const Odometry& odom) {
  if (!exchange_ticks_) TakeArrived();  // in lockstep, at the tick
  if (sync_.frame_fixed() && options_.exchange.ByRendezvous()) {
    rendezvous_.OnPose(sync_.processed_until(), mapper_->pose(), mapper_->pose_cov());
    if (!exchange_ticks_) {  // in lockstep, at the tick
      PublishSightings(rendezvous_.Advance(sync_.processed_until()));
      for (const auto& [key, fit] : rendezvous_.TakeFits()) exchange_.OnRendezvous(key, fit);
    }
  }
  // Before the frame is fixed the robot's place in it is not known yet.
  if (sync_.frame_fixed() && sync_.processed_until() + 1e-9 >= next_trajectory_s_) {
    trajectory_.push_back({sync_.processed_until(), mapper_->pose()});
    next_trajectory_s_ = sync_.processed_until() + trajectory_period_s_;
  }
  if (!exchange_ticks_ && sync_.processed_until() + 1e-9 >= next_map_publish_s_) {
    PublishMaps(0);
    next_map_publish_s_ = (std::floor(sync_.processed_until() / options_.exchange.map_publish_period_s + 1e-9) + 1.0) *
                          options_.exchange.map_publish_period_s;
  }
  bool status_due = odom.sync;
  if (sync_.processed_until() + 1e-9 >= next_status_s_) {
    status_due = true;
    next_status_s_ = (std::floor(sync_.processed_until() / options_.status_period_s + 1e-9) + 1.0) *
                     options_.status_period_s;
  }
  if (status_due) out_.PublishStatus(Status());
}

void AgentNode::PublishMaps(std::uint32_t tick, std::vector<Sighting> riders) {
  const LandmarkMap local = mapper_->Map();
  // Once this session's frame is fixed: earlier incarnations that began where it did share it.
  if (!continuity_checked_ && sync_.frame_fixed() && sync_.frame_origin_stamp()) {
    continuity_checked_ = true;
    exchange_.PlaceOwnCheckpointsAt(*sync_.frame_origin_stamp(), local, sync_.processed_until());
  }
  TakeOwnSubmaps();
  if (joining_) {
    own_open_ = mapper_->CurrentSubmap({self_, incarnation_, static_cast<std::uint32_t>(own_submaps_taken_)});
    exchange_.SetSubmapInputs({.book = &submaps_.book(),
                               .own_open = own_open_ ? &*own_open_ : nullptr,
                               .peers_open = &submaps_.open(),
                               .peers_placements = &peers_placements_,
                               .heard = &heard_});
  } else if (options_.exchange.ci_placement == CiPlacement::kPiecewise) {
    exchange_.SetSubmapInputs({.book = &submaps_.book(), .heard = &heard_});
  }
  exchange_.Update(local, sync_.processed_until());
  Publish(MapKind::kLocal, local, ++local_version_, tick, riders);
  // A joining agent's peers join one-hop local maps and submaps only (a relayed global map
  // mixes information of unknown origin; submaps reach every hop by identity), so its global
  // map stays off the wire: on park4 it was 30 % of the bytes a joining agent sent.
  if (!joining_) Publish(MapKind::kGlobal, exchange_.published().map, ++global_version_, tick, riders);
  stats_.sightings_unsent += static_cast<std::uint32_t>(riders.size());  // no map could be encoded
}

void AgentNode::TakeOwnSubmaps() {
  for (; own_submaps_taken_ < mapper_->SubmapsClosed(); ++own_submaps_taken_) {
    const SubmapId id{self_, incarnation_, static_cast<std::uint32_t>(own_submaps_taken_)};
    const std::optional<WireSubmap> w = mapper_->ClosedSubmap(own_submaps_taken_, id);
    const std::vector<std::uint8_t> bytes = w ? EncodeSubmap(*w) : std::vector<std::uint8_t>{};
    if (bytes.empty()) {
      ++stats_.submaps_unsendable;
      continue;
    }
    submaps_.AddOwn(*w, bytes, SignOwn(bytes));
  }
}

std::vector<std::uint8_t> AgentNode::SignOwn(std::span<const std::uint8_t> bytes) const {
  return origin_ == nullptr ? std::vector<std::uint8_t>{} : origin_->Sign(bytes);
}

bool AgentNode::Authentic(const WireSubmap& s, std::span<const std::uint8_t> bytes,
                          std::span<const std::uint8_t> signature) {
  if (origin_ == nullptr) return true;
  switch (origin_->Verify(s.id.robot, bytes, signature)) {
    case SubmapOrigin::Verdict::kValid: return true;
    case SubmapOrigin::Verdict::kUnsigned: ++stats_.submaps_refused[static_cast<int>(SubmapRefusal::kUnsigned)]; break;
    case SubmapOrigin::Verdict::kUnknownSigner:
      ++stats_.submaps_refused[static_cast<int>(SubmapRefusal::kUnknownSigner)];
      break;
    case SubmapOrigin::Verdict::kForged:
      ++stats_.submaps_refused[static_cast<int>(SubmapRefusal::kForgedSignature)];
      break;
  }
  return false;
}

bool AgentNode::Publish(MapKind kind, const LandmarkMap& map, std::uint32_t version, std::uint32_t tick,
                        std::vector<Sighting>& riders) {
  MapMessage msg;
  msg.robot_id = self_;
  msg.kind = kind;
  msg.incarnation = incarnation_;
  msg.version = version;
  msg.tick = tick;
  msg.stamp = sync_.processed_until();
  msg.origin_stamp = sync_.frame_origin_stamp().value_or(0.0);
  MapDecodeError why = MapDecodeError::kOk;
  msg.payload = EncodeMap(map, &why);
  std::size_t landmarks = map.size();
  if (msg.payload.empty() && why == MapDecodeError::kOutOfBounds) {
    // A landmark beyond what a map can carry (a robot 8 km from its frame's origin) must not
    // silence the agent: the rest of the map goes out.
    LandmarkMap within = map;
    std::erase_if(within.landmarks, [](const Landmark& l) {
      return !(std::abs(l.mean.x()) <= kMapCodecMaxCoordinateM && std::abs(l.mean.y()) <= kMapCodecMaxCoordinateM);
    });
    msg.payload = EncodeMap(within, &why);
    landmarks = within.size();
    if (!msg.payload.empty()) ++stats_.maps_encode_trimmed;
  }
  if (msg.payload.empty()) {
    ++stats_.maps_encode_failed;
    stats_.last_encode_error = why;
    return false;
  }
  if (kind == MapKind::kLocal) {
    // The submap chains held, and what the peers in range lack of them (SubmapRelay).
    std::set<RobotId> in_range;
    for (RobotId r : robot_ids_) {
      if (r != self_ && gate_.InRange(r)) in_range.insert(r);
    }
    msg.submaps_held = submaps_.Advert();
    msg.own_submap_digests = submaps_.OwnDigests({self_, incarnation_});
    std::size_t spent = 0;  // one send_bytes budget for the closed and the open submaps relayed
    for (const SubmapBlob* b : submaps_.Due(in_range, sync_.processed_until())) {
      msg.submaps.push_back(*b);
      spent += b->bytes.size();
    }
    if (own_open_) {
      msg.open_submap = EncodeSubmap(*own_open_);
      if (!msg.open_submap.empty()) msg.open_submap_signature = SignOwn(msg.open_submap);
    }
    if (joining_) {
      for (const SubmapBlob* b : submaps_.DueOpen(in_range, sync_.processed_until(), spent))
        msg.open_relayed.push_back(*b);
      // Only what a receiver takes (PlausiblePlacements), so that one chain placed beyond a map's
      // bound does not make the peers refuse all of them.
      for (const ChainPlacement& c : exchange_.placements()) {
        if (msg.placements.size() < MaxPlacements() && PlausiblePlacement(c, self_, incarnation_))
          msg.placements.push_back(c);
      }
    }
  }
  // Beyond what every agent of the run takes (MaxSampleBytes: their settings are its own), the
  // transport would refuse to write it: not sent, counted (the wire's bound is not the codec's).
  if (WireBytes(msg) + riders.size() * kSightingWireBytes > max_sample_bytes_) {
    ++stats_.maps_beyond_sample_size;
    return false;
  }
  ++stats_.maps_sent;
  stats_.bytes_sent += WireBytes(msg);
  stats_.landmarks_sent += landmarks;
  stats_.payload_bytes_sent += msg.payload.size();
  stats_.open_submap_bytes_sent += msg.open_submap.size();
  stats_.sightings_sent += static_cast<std::uint32_t>(riders.size());
  stats_.sighting_bytes_sent += riders.size() * kSightingWireBytes;
  msg.sightings = std::move(riders);
  riders.clear();
  out_.PublishMap(msg);
  return true;
}

void AgentNode::OnLinks(const RadioLinks& links) {
  gate_.UpdateLinks(links, sync_.processed_until());
  sighting_gate_.UpdateLinks(links, sync_.processed_until());
  stats_.links_refused = gate_.links_refused();
}

double AgentNode::Clock() const { return std::max(sync_.processed_until(), gate_.links_stamp()); }

void AgentNode::OnMap(const MapMessage& msg, const std::string& writer) {
  // Our own publications echo back; an earlier incarnation of ours comes from the checkpoint.
  if (msg.robot_id == self_) return;
  // Another writer than the robot incarnation's (its riders with it): refused before it is kept.
  if (!writers_.Admits(msg.robot_id, msg.incarnation, writer)) {
    ++stats_.maps_refused[static_cast<int>(MapRefusal::kOtherWriter)];
    return;
  }
  // Lockstep: into the inbox, with its riders (each must be the publisher's, of the map's tick).
  if (exchange_ticks_) {
    stats_.sightings_implausible += inbox_.OfferMap(msg, writer).foreign_riders;
    return;
  }
  // Sightings riding on the map are the publisher's own, or refused.
  for (const Sighting& s : msg.sightings) {
    if (s.robot_id != msg.robot_id || s.incarnation != msg.incarnation || s.tick != msg.tick) {
      ++stats_.sightings_implausible;
    } else {
      OnSighting(s);
    }
  }
  ProcessMap(msg, writer);
}

void AgentNode::RefuseMap(MapRefusal r) { ++stats_.maps_refused[static_cast<int>(r)]; }

void AgentNode::RefuseRiders(const MapMessage& msg) {
  // What rides on a map is taken only with the map (issue R3: a stale copy of a peer's map
  // carried forged submaps and placements in, and its older advertisement replaced the newer).
  const std::size_t riders = msg.submaps.size() + msg.open_relayed.size() + (msg.open_submap.empty() ? 0 : 1);
  stats_.submaps_refused[static_cast<int>(SubmapRefusal::kOnRefusedMap)] += static_cast<std::uint32_t>(riders);
}

void AgentNode::ProcessMap(const MapMessage& msg, const std::string& writer) {
  if (!InRun(msg.robot_id)) {
    ++stats_.maps_unknown_sender;
    return;
  }
  const double now = Clock();
  // Kept in the inbox before the robot incarnation's first map was taken, from another writer;
  // else the first map with a plausible stamp binds its writer, whether or not the radio lets
  // it through (the writer is a fact of the transport, not of range).
  if (!writers_.Admits(msg.robot_id, msg.incarnation, writer)) {
    RefuseRiders(msg);
    return RefuseMap(MapRefusal::kOtherWriter);
  }
  if (!std::isfinite(msg.stamp) || !std::isfinite(msg.origin_stamp) || msg.stamp > now + options_.max_stamp_jump_s) {
    return RefuseMap(MapRefusal::kImplausibleStamp);
  }
  writers_.Bind(msg.robot_id, msg.incarnation, writer);
  switch (gate_.Admit(msg.robot_id, WireBytes(msg), msg.stamp)) {
    case GateVerdict::kOutOfRange: ++stats_.maps_out_of_range; return;
    case GateVerdict::kLost: ++stats_.maps_lost; return;
    case GateVerdict::kBusy: ++stats_.maps_over_bandwidth; return;
    case GateVerdict::kPass: break;
  }
  if (gate_.Delays()) {
    const double arrival = gate_.Arrival(msg.robot_id, WireBytes(msg), msg.stamp);
    if (arrival > RadioNow() + kArrivalSlackS) {
      if (delay_.Hold(arrival, msg, writer, WireBytes(msg))) {
        ++stats_.maps_delayed;
      } else {
        ++stats_.maps_delay_overflow;
      }
      stats_.in_flight = static_cast<std::uint32_t>(delay_.size());
      return;
    }
  }
  ApplyMap(msg);
}

void AgentNode::ApplyMap(const MapMessage& msg) {
  const double now = Clock();
  stats_.bytes_received += WireBytes(msg);
  // A map larger than we will align is refused before it is decoded (kept within the codec's
  // own limit, so that a malformed count is still reported as such).
  if (const auto n = MapPayloadCount(msg.payload);
      n && *n <= kMapCodecMaxLandmarks && *n > options_.peer_limits.max_landmarks) {
    RefuseRiders(msg);
    return RefuseMap(MapRefusal::kTooManyLandmarks);
  }
  MapDecodeResult decoded = DecodeMap(msg.payload);
  if (!decoded.ok()) {
    RefuseRiders(msg);
    ++stats_.maps_rejected[static_cast<int>(decoded.error)];
    return;
  }
  const MapLimitViolation limits = CheckMapLimits(decoded.map, options_.peer_limits);
  if (limits != MapLimitViolation::kNone) RefuseRiders(msg);
  switch (limits) {
    case MapLimitViolation::kNone: break;
    case MapLimitViolation::kTooManyLandmarks: return RefuseMap(MapRefusal::kTooManyLandmarks);
    case MapLimitViolation::kOutOfWorld: return RefuseMap(MapRefusal::kOutOfWorld);
    case MapLimitViolation::kCovarianceTooLarge: return RefuseMap(MapRefusal::kCovarianceTooLarge);
    case MapLimitViolation::kCovarianceTooSmall: return RefuseMap(MapRefusal::kCovarianceTooSmall);
  }
  switch (exchange_.OnPeerMap(msg.robot_id, msg.incarnation, msg.kind, msg.version, msg.origin_stamp,
                              std::move(decoded.map), now)) {
    case MapExchange::Receipt::kAccepted: break;
    case MapExchange::Receipt::kStaleVersion:
      RefuseRiders(msg);
      ++stats_.maps_stale_version;
      return;
    case MapExchange::Receipt::kVersionJump: RefuseRiders(msg); return RefuseMap(MapRefusal::kVersionJump);
    case MapExchange::Receipt::kTooManyIncarnations:
      RefuseRiders(msg);
      return RefuseMap(MapRefusal::kTooManyIncarnations);
  }
  heard_.insert({msg.robot_id, msg.incarnation});
  if (msg.kind == MapKind::kLocal) ProcessSubmaps(msg, now);
  ++stats_.maps_received;
  ++stats_.maps_received_from[msg.robot_id];
  double& until = stats_.data_until[msg.robot_id];
  until = std::max(until, msg.stamp);
}

void AgentNode::ProcessSubmaps(const MapMessage& msg, double now) {
  submaps_.OnAdvert({msg.robot_id, msg.incarnation}, msg.submaps_held, now);
  // The owner's word on its own chain (issue R3): this map is the robot's own (its writer's),
  // so copies held that disagree with it go, and the owner's come instead. An advertisement
  // cut at its chain limit may leave the owner's chain out: then it says nothing.
  const auto own = std::find_if(msg.submaps_held.begin(), msg.submaps_held.end(), [&](const SubmapChain& c) {
    return c.robot == msg.robot_id && c.incarnation == msg.incarnation;
  });
  if (own != msg.submaps_held.end() || msg.submaps_held.size() < SubmapRelay::kMaxChains) {
    submaps_.OnOwnerAdvert({msg.robot_id, msg.incarnation}, own != msg.submaps_held.end() ? own->count : 0,
                           msg.own_submap_digests);
  }
  auto refuse = [this](SubmapRefusal r) { ++stats_.submaps_refused[static_cast<int>(r)]; };
  // The robot, the stamp and the limits, for every submap taken (a peer's open one too).
  auto admissible = [&](const WireSubmap& s) {
    if (!InRun(s.id.robot)) {
      refuse(SubmapRefusal::kUnknownRobot);
      return false;
    }
    if (s.id.robot == self_) {  // the agent is its robot's only source (issue R3)
      refuse(SubmapRefusal::kOwnRobot);
      return false;
    }
    // Within the run: opened no earlier than its start (scenario time 0), closed no later than
    // what the agent has received.
    if (s.opened_s < 0.0 || s.closed_s > now + options_.max_stamp_jump_s) {
      refuse(SubmapRefusal::kImplausibleStamp);
      return false;
    }
    switch (CheckSubmapLimits(s, options_.peer_limits)) {
      case MapLimitViolation::kNone: return true;
      case MapLimitViolation::kTooManyLandmarks: refuse(SubmapRefusal::kTooManyLandmarks); break;
      case MapLimitViolation::kOutOfWorld: refuse(SubmapRefusal::kOutOfWorld); break;
      case MapLimitViolation::kCovarianceTooLarge: refuse(SubmapRefusal::kCovarianceTooLarge); break;
      case MapLimitViolation::kCovarianceTooSmall: refuse(SubmapRefusal::kCovarianceTooSmall); break;
    }
    return false;
  };
  // Open submaps: the publisher's own, and silent robots' it relays. The latest of each robot
  // incarnation is kept (an older one arriving late changes nothing); never one of ours.
  // Longer than any submap a real chain makes: refused before it is decoded (issue R3).
  const auto too_large = [&](const std::vector<std::uint8_t>& bytes) {
    if (bytes.size() <= options_.exchange.submaps.max_submap_bytes) return false;
    refuse(SubmapRefusal::kTooLarge);
    return true;
  };
  const auto take_open = [&](const std::vector<std::uint8_t>& bytes, std::span<const std::uint8_t> signature,
                             bool relayed) {
    if (too_large(bytes)) return;
    const SubmapDecodeResult d = DecodeSubmap(bytes);
    // The signature is checked once per version kept (the same bytes again change nothing).
    const auto fresh = [&] {
      const std::vector<std::uint8_t>* kept = submaps_.OpenBytes({d.submap.id.robot, d.submap.id.incarnation});
      return kept == nullptr || *kept != bytes;
    };
    const bool publishers = d.submap.id.robot == msg.robot_id && d.submap.id.incarnation == msg.incarnation;
    if (!d.ok()) {
      ++stats_.submaps_rejected[static_cast<int>(d.error)];
    } else if (!relayed && !publishers) {
      refuse(SubmapRefusal::kNotThePublishers);
    } else if (relayed && d.submap.id.robot == msg.robot_id) {
      refuse(SubmapRefusal::kOpenRelayedByItsRobot);
    } else if (admissible(d.submap) && (!fresh() || Authentic(d.submap, bytes, signature)) &&
               submaps_.AddOpen(d.submap, bytes, now, relayed, signature) == SubmapRelay::Offer::kNew) {
      double& until = stats_.data_until[d.submap.id.robot];  // the join may use it: its data reached us
      until = std::max(until, d.submap.closed_s);
    }
  };
  if (joining_ && !msg.open_submap.empty()) take_open(msg.open_submap, msg.open_submap_signature, false);
  for (std::size_t i = 0; joining_ && i < msg.open_relayed.size(); ++i) {
    if (i >= kMaxSubmapsPerMap) {
      refuse(SubmapRefusal::kTooManyOnOneMap);
      continue;
    }
    take_open(msg.open_relayed[i].bytes, msg.open_relayed[i].signature, true);
  }
  if (joining_ && !msg.placements.empty()) {
    const PeerKey key{msg.robot_id, msg.incarnation};
    const auto held = placements_version_.find(key);
    if (!PlausiblePlacements(msg)) {
      refuse(SubmapRefusal::kImplausiblePlacements);
    } else if (held == placements_version_.end() || msg.version > held->second) {
      placements_version_[key] = msg.version;
      peers_placements_[key] = msg.placements;
    }
  }
  for (std::size_t i = 0; i < msg.submaps.size(); ++i) {
    if (i >= kMaxSubmapsPerMap) {
      refuse(SubmapRefusal::kTooManyOnOneMap);
      continue;
    }
    const SubmapBlob& blob = msg.submaps[i];
    if (too_large(blob.bytes)) continue;
    const SubmapDecodeResult d = DecodeSubmap(blob.bytes);
    if (!d.ok()) {
      ++stats_.submaps_rejected[static_cast<int>(d.error)];
      continue;
    }
    if (!admissible(d.submap)) continue;
    // A submap held already is a duplicate whatever it is signed with; any other enters (or
    // counts as a conflict) only with its robot's signature (secure runs).
    const std::vector<std::uint8_t>* held = submaps_.book().Bytes(d.submap.id);
    if ((held == nullptr || *held != blob.bytes) && !Authentic(d.submap, blob.bytes, blob.signature)) continue;
    submaps_.Add(d.submap, blob.bytes, now, blob.signature);
  }
}

std::size_t AgentNode::MaxPlacements() const {
  return robot_ids_.size() * static_cast<std::size_t>(options_.exchange.max_incarnations);
}

bool AgentNode::PlausiblePlacement(const ChainPlacement& c, RobotId publisher, std::uint32_t incarnation) const {
  const bool within = std::abs(c.x) <= kMapCodecMaxCoordinateM && std::abs(c.y) <= kMapCodecMaxCoordinateM &&
                      std::isfinite(c.theta);
  return within && InRun(c.robot) && !(c.robot == publisher && c.incarnation == incarnation);
}

bool AgentNode::PlausiblePlacements(const MapMessage& msg) const {
  if (msg.placements.size() > MaxPlacements()) return false;
  for (std::size_t i = 0; i < msg.placements.size(); ++i) {
    const ChainPlacement& c = msg.placements[i];
    const bool ordered = i == 0 || std::tie(msg.placements[i - 1].robot, msg.placements[i - 1].incarnation) <
                                       std::tie(c.robot, c.incarnation);
    if (!ordered || !PlausiblePlacement(c, msg.robot_id, msg.incarnation)) return false;
  }
  return true;
}

bool AgentNode::InRun(RobotId robot) const {
  return std::find(robot_ids_.begin(), robot_ids_.end(), robot) != robot_ids_.end();
}

bool AgentNode::OnTick(const ExchangeTick& tick) {
  if (!exchange_ticks_) return true;
  inbox_.OnTick(tick.index, tick.peers);
  const bool listed = std::any_of(tick.peers.begin(), tick.peers.end(),
                                  [&](const TickPeer& p) { return p.robot == self_ && p.incarnation == incarnation_; });
  if (!listed) return true;  // a tick from before this incarnation was up
  if (tick.phase == TickPhase::kDeliver) {
    if (tick.index <= tick_delivered_) return true;
    if (!Missing(tick).empty()) return false;
    tick_delivered_ = tick.index;
    out_.PublishStatus(Status());
    return true;
  }
  if (tick.index <= tick_done_) return true;
  Exchange(tick);
  return true;
}

void AgentNode::Exchange(const ExchangeTick& tick) {
  if (!first_tick_) first_tick_ = tick.index;
  // The feeder lists the incarnations up: each is heard. Only the ticks this incarnation
  // exchanges at count (which earlier ones reach a restarted agent depends on the host).
  for (const TickPeer& p : tick.peers) heard_.insert({p.robot, p.incarnation});
  // The gates judge the tick's messages by the tick's link table (from the feeder, like the
  // sensor data), whatever has come in on the links topic since.
  if (tick.links.stamp >= 0.0) {
    gate_.SetLinks(tick.links);
    sighting_gate_.SetLinks(tick.links);
  }
  tick_stamp_ = tick.stamp;
  ApplyInbox(tick.index);
  // Exactly the incarnations the tick lists are alive (after the inbox: a map of an incarnation
  // that has died since it was published must not make it alive again).
  std::set<PeerKey> live;
  for (const TickPeer& p : tick.peers) live.insert({p.robot, p.incarnation});
  exchange_.SetLive(live, sync_.processed_until());
  if (sync_.frame_fixed() && options_.exchange.ByRendezvous()) {
    PublishSightings(rendezvous_.Advance(sync_.processed_until()));
    for (const auto& [key, fit] : rendezvous_.TakeFits()) exchange_.OnRendezvous(key, fit);
  }
  // The tick's sightings and answers ride on its maps: rendezvous adds no message of its own
  // (at 64 agents, about three sightings per agent and tick were as many again as the maps).
  std::vector<Sighting> riders = std::move(held_sightings_);
  held_sightings_.clear();
  // At most what a peer's inbox takes on one map (a restarted agent's replay makes one sighting
  // per peer and period of all of it before its first tick): the newest, those still answerable.
  if (riders.size() > inbox_.sightings_per_map()) {
    const std::size_t drop = riders.size() - inbox_.sightings_per_map();
    stats_.sightings_unsent += static_cast<std::uint32_t>(drop);
    riders.erase(riders.begin(), riders.begin() + static_cast<std::ptrdiff_t>(drop));
  }
  for (Sighting& r : riders) r.tick = tick.index;
  const std::uint32_t sent_before = stats_.maps_sent;
  PublishMaps(tick.index, std::move(riders));
  tick_done_ = tick.index;
  tick_published_ = stats_.maps_sent - sent_before;
  if (options_.checkpoint_period_s > 0 && tick.stamp + 1e-9 >= next_checkpoint_s_) {
    checkpoint_due_ = true;
    next_checkpoint_s_ = tick.stamp + options_.checkpoint_period_s;
  }
  out_.PublishStatus(Status());
}

void AgentNode::ApplyInbox(std::uint32_t tick) {
  // Untagged messages (tick 0: from outside the run's agents) are applied at the next tick too;
  // those of ticks before this incarnation's first (a late reader gets them from the writers'
  // history) are not for it (the inbox drops them).
  TakeArrived();  // first what has arrived over its links by now, then what came for this tick
  LockstepInbox::Due due = inbox_.TakeBefore(tick);
  for (std::size_t i = 0; i < due.maps.size(); ++i) ProcessMap(due.maps[i], due.writers[i]);
  if (!options_.exchange.ByRendezvous()) return;
  for (const Sighting& s : due.sightings) ProcessSighting(s);
}

std::vector<TickPeer> AgentNode::Missing(const ExchangeTick& tick) const { return inbox_.Missing(tick); }

bool AgentNode::TakeCheckpointDue() { return std::exchange(checkpoint_due_, false); }

bool AgentNode::OnPeerLiveliness(RobotId robot, bool alive) {
  if (exchange_ticks_ || robot == self_ || !InRun(robot)) return false;
  exchange_.OnPeerLiveliness(robot, alive, sync_.processed_until());
  return true;
}

void AgentNode::Resume(const AgentCheckpoint& c) {
  const auto add = [this](const IncarnationSnapshot& s) {
    MAPMESH_CHECK(s.robot == self_ && s.incarnation != incarnation_,
                  "a checkpoint not validated by io::LoadCheckpoint");
    exchange_.AddOwnCheckpoint(s.incarnation, s.origin_stamp, s.local, s.global);
    heard_.insert({self_, s.incarnation});  // the agent's own history
  };
  add(c);
  for (const IncarnationSnapshot& e : c.earlier) add(e);
  // The peers' frames it had placed: weighed on the maps once this session's frame is the one
  // they are in (PeerBook::UseCarriedIn), not searched for again (issue R3).
  std::vector<PeerAlignment> peers;
  for (const PeerAlignment& a : c.peers) {
    if (InRun(a.robot)) peers.push_back(a);
  }
  exchange_.AddCarried(std::move(peers));
  for (const SubmapBlob& blob : c.submaps) {
    const std::vector<std::uint8_t>& bytes = blob.bytes;
    const SubmapDecodeResult d = DecodeSubmap(bytes);
    MAPMESH_CHECK(d.ok() && !(d.submap.id.robot == self_ && d.submap.id.incarnation == incarnation_),
                  "a checkpoint not validated by io::LoadCheckpoint");
    if (!InRun(d.submap.id.robot)) {
      ++stats_.submaps_refused[static_cast<int>(SubmapRefusal::kUnknownRobot)];
      continue;
    }
    if (Authentic(d.submap, bytes, blob.signature)) submaps_.Restore(d.submap, bytes, blob.signature);
  }
}

AgentCheckpoint AgentNode::Checkpoint(std::size_t* left_out, std::size_t* submaps_left_out) const {
  AgentCheckpoint c;
  c.robot = self_;
  c.incarnation = incarnation_;
  c.origin_stamp = sync_.frame_origin_stamp().value_or(0.0);
  c.processed_until = sync_.processed_until();
  c.local = mapper_->Map();
  c.global = exchange_.global().map;
  c.peers = exchange_.Alignments(c.origin_stamp);
  if (c.peers.size() > io::CheckpointLimits{}.max_peers) c.peers.resize(io::CheckpointLimits{}.max_peers);
  for (const auto& e : exchange_.UnalignedOwnCheckpoints()) {
    IncarnationSnapshot old;
    old.robot = self_;
    old.incarnation = e.incarnation;
    old.origin_stamp = e.origin_stamp;
    old.local = e.local;
    old.global = e.global;
    c.earlier.push_back(std::move(old));
  }
  // A checkpoint with more earlier incarnations than the loader accepts could not be resumed
  // from at all: keep the newest (UnalignedOwnCheckpoints is in incarnation order).
  const std::size_t cap = io::CheckpointLimits{}.max_earlier;
  const std::size_t extra = c.earlier.size() > cap ? c.earlier.size() - cap : 0;
  c.earlier.erase(c.earlier.begin(), c.earlier.begin() + static_cast<std::ptrdiff_t>(extra));
  if (left_out != nullptr) *left_out = extra;
  // The closed submaps held, the own robot's first (its chains are what only it may lack after
  // a restart), as many as the loader accepts, in count and in bytes (issue R3: a checkpoint
  // past the loader's file limit could not be resumed from).
  std::vector<SubmapId> ids = submaps_.book().Ids();
  std::stable_partition(ids.begin(), ids.end(), [this](const SubmapId& id) { return id.robot == self_; });
  const io::CheckpointLimits limits;
  std::size_t kept = 0, bytes = 0;
  for (; kept < ids.size() && kept < limits.max_submaps; ++kept) {
    const SubmapBlob* b = submaps_.book().Blob(ids[kept]);
    if (bytes + b->bytes.size() + b->signature.size() > limits.max_submap_bytes) break;
    bytes += b->bytes.size() + b->signature.size();
  }
  if (submaps_left_out != nullptr) *submaps_left_out = ids.size() - kept;
  ids.resize(kept);
  std::sort(ids.begin(), ids.end());
  c.submaps.reserve(ids.size());
  for (const SubmapId& id : ids) c.submaps.push_back(*submaps_.book().Blob(id));
  return c;
}

AgentStatus AgentNode::Status() const {
  AgentStatus s;
  s.robot_id = self_;
  s.incarnation = incarnation_;
  s.processed_until = sync_.processed_until();
  s.odom_processed = sync_.stats().odom_processed;
  s.scans_processed = sync_.stats().scans_processed;
  s.local_landmarks = static_cast<std::uint32_t>(mapper_->size());
  s.global_landmarks = static_cast<std::uint32_t>(std::max(exchange_.global().map.size(), mapper_->size()));
  s.peers_aligned = exchange_.AlignedRobots();
  s.peers_stale = exchange_.StaleRobots();
  s.maps_received = stats_.maps_received;
  s.maps_dropped = stats_.MapsDropped();
  s.bytes_sent = stats_.bytes_sent;
  s.bytes_received = stats_.bytes_received;
  s.tick_done = tick_done_;
  s.tick_published = tick_published_;
  s.tick_delivered = tick_delivered_;
  return s;
}

}  // namespace mapmesh
