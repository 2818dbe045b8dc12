#include "agent/agent_node.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/check.h"
#include "common/slam/dead_reckoning_mapper.h"
#include "common/slam/local_slam.h"

namespace mapmesh {
namespace {

// MapMessage fields besides the payload: robot_id, kind, version, stamp, sequence length.
constexpr std::size_t kMapMessageFixedBytes = 4 + 1 + 4 + 4 + 8 + 8 + 4;  // keys, incarnation, version, stamps, payload length

// No stamp of the run comes after this: its end when the scenario says (a dataset replayed
// whole ends where its data does, which the agent does not read), and a window's slack.
double RunEnd(const Scenario& sc) {
  return sc.source.IsDataset() && !sc.duration_given ? std::numeric_limits<double>::infinity()
                                                     : sc.duration_s + sc.agent.max_stamp_jump_s;
}

}  // namespace

std::unique_ptr<LocalMapper> MakeLocalMapper(const Scenario& sc, RobotId self) {
  const RobotSpec* robot = sc.FindRobot(self);
  MAPMESH_CHECK(robot != nullptr, "agent id not in the scenario");
  const AgentOptions& a = sc.agent;
  const MotionModel motion = MotionModelFor(robot->motion);
  if (a.slam == "dead_reckoning") {
    DeadReckoningOptions o;
    o.motion = motion;
    o.sigma_range_m = robot->sensor.sigma_range_m;
    o.sigma_bearing_rad = DegToRad(robot->sensor.sigma_bearing_deg);
    o.association_gate_m = a.association_gate_m;
    return std::make_unique<DeadReckoningMapper>(o);
  }
  FilterNoise noise;
  noise.motion = motion;
  const double sigma_turn = motion.kind == MotionModel::Kind::kAckermann ? robot->motion.sigma_steering_rad
                                                                         : robot->motion.sigma_w_radps;
  noise.control_cov = Eigen::Vector2d(std::pow(robot->motion.sigma_v_mps, 2), sigma_turn * sigma_turn).asDiagonal();
  noise.control_period_s = sc.world.control_period_s;
  noise.obs_cov = Eigen::Vector2d(std::pow(robot->sensor.sigma_range_m, 2),
                                  std::pow(DegToRad(robot->sensor.sigma_bearing_deg), 2))
                      .asDiagonal();
  LocalSlamOptions o;
  o.filter = a.slam;
  std::string method = a.association;
  if (method == "auto") method = robot->sensor.signatures ? "known" : "jcbb";
  o.association.method = method == "known" ? AssociationMethod::kKnown
                         : method == "icnn" ? AssociationMethod::kIcnn
                                            : AssociationMethod::kJcbb;
  o.association.gate_probability = a.gate_probability;
  o.association.new_landmark_chi2 = a.new_landmark_chi2;
  o.tentative = a.tentative;
  o.tentative_gate_m = a.tentative_gate_m;
  o.tentative_timeout_s = a.tentative_timeout_s;
  o.min_range_m = a.min_range_m;
  // Readings beyond what the sensor can see (allowing for its noise) are refused: one forged
  // reading 30 km away must not end up in the map.
  o.max_range_m = a.max_range_m > 0 ? a.max_range_m : robot->sensor.max_range_m + 5.0 * robot->sensor.sigma_range_m;
  o.ekf.first_estimates_jacobians = a.first_estimates_jacobians;
  o.cekf.region_half_m = a.region_half_m;
  const double range = a.max_range_m > 0 ? a.max_range_m : robot->sensor.max_range_m;
  o.cekf.reach_m = a.region_reach_m > 0 ? a.region_reach_m : range + 4.0;
  return std::make_unique<LocalSlam>(noise, o);
}

ExchangeOptions ExchangeOptionsFor(const Scenario& sc) {
  const AgentOptions& a = sc.agent;
  ExchangeOptions o;
  o.align_period_s = a.align_period_s;
  o.refine_period_s = a.refine_period_s;
  o.drop_after_failures = a.drop_after_failures;
  o.relay_global_maps = a.relay_global_maps;
  o.silent_after_s = a.silent_after_s > 0 ? a.silent_after_s : 3.0 * a.map_publish_period_s;
  o.max_alignments_per_update = a.max_alignments_per_update;
  o.max_versions_per_s = 2.0 / a.map_publish_period_s;  // one of each kind per period, twice over
  const std::optional<FusionMethod> m = ParseFusionMethod(a.fusion);
  MAPMESH_CHECK(m.has_value(), "agent.fusion was validated when the scenario was read");
  o.global.method = *m;
  return o;
}

std::size_t WireBytes(const MapMessage& msg) { return kMapMessageFixedBytes + msg.payload.size(); }

std::string_view ToString(MapRefusal r) {
  switch (r) {
    case MapRefusal::kImplausibleStamp: return "implausible_stamp";
    case MapRefusal::kTooManyLandmarks: return "too_many_landmarks";
    case MapRefusal::kOutOfWorld: return "out_of_world";
    case MapRefusal::kCovarianceTooLarge: return "covariance_too_large";
    case MapRefusal::kVersionJump: return "version_jump";
    case MapRefusal::kTooManyIncarnations: return "too_many_incarnations";
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
  return maps_out_of_range + maps_lost + maps_over_bandwidth + maps_unknown_sender + maps_stale_version + MapsRejected() +
         MapsRefused();
}

AgentNode::AgentNode(const Scenario& scenario, RobotId self, std::uint32_t incarnation,
                     AgentOutput& out)
    : options_(scenario.agent),
      peer_limits_{static_cast<std::size_t>(scenario.agent.max_peer_landmarks), scenario.agent.world_radius_m,
                   scenario.agent.max_landmark_sigma_m},
      self_(self),
      incarnation_(incarnation),
      out_(out),
      gate_(self,
            RadioGateOptions{scenario.radio.loss_probability, scenario.radio.bandwidth_bytes_per_s,
                             scenario.agent.max_stamp_jump_s, RunEnd(scenario)},
            scenario.seed * 1000003ULL + self * 7919ULL + incarnation),
      sync_(*this, SensorSync::Options{scenario.agent.frame_at_first_landmark, scenario.agent.max_stamp_jump_s,
                                       RunEnd(scenario)}),
      mapper_(MakeLocalMapper(scenario, self)),
      trajectory_period_s_(scenario.feeder.truth_period_s),
      exchange_(self, incarnation, ExchangeOptionsFor(scenario),
                scenario.seed * 2654435761ULL + self * 40503ULL + incarnation) {
  for (const auto& r : scenario.robots) robot_ids_.push_back(r.id);
}

void AgentNode::OnOdometry(const Odometry& odom) { sync_.OnOdometry(odom); }

void AgentNode::OnScan(const Scan& scan) { sync_.OnScan(scan); }

void AgentNode::Move(const OdometryControl& u, double dt) { mapper_->Predict(u, dt); }

void AgentNode::ApplyScan(const Scan& scan, double stamp) { mapper_->Observe(scan.obs, stamp); }

void AgentNode::IntervalDone(const Odometry& odom) { AfterInterval(odom); }

bool AgentNode::Mapped() const { return mapper_->size() > 0; }

void AgentNode::AfterInterval(const Odometry& odom) {
  // Before the frame is fixed the robot's place in it is not known yet.
  if (sync_.frame_fixed() && sync_.processed_until() + 1e-9 >= next_trajectory_s_) {
    trajectory_.push_back({sync_.processed_until(), mapper_->pose()});
    next_trajectory_s_ = sync_.processed_until() + trajectory_period_s_;
  }
  if (sync_.processed_until() + 1e-9 >= next_map_publish_s_) {
    PublishMaps();
    next_map_publish_s_ =
        (std::floor(sync_.processed_until() / options_.map_publish_period_s + 1e-9) + 1.0) *
        options_.map_publish_period_s;
  }
  bool status_due = odom.sync;
  if (sync_.processed_until() + 1e-9 >= next_status_s_) {
    status_due = true;
    next_status_s_ = (std::floor(sync_.processed_until() / options_.status_period_s + 1e-9) + 1.0) *
                     options_.status_period_s;
  }
  if (status_due) out_.PublishStatus(Status());
}

void AgentNode::PublishMaps() {
  const LandmarkMap local = mapper_->Map();
  exchange_.Update(local, sync_.processed_until());
  Publish(MapKind::kLocal, local, ++local_version_);
  Publish(MapKind::kGlobal, exchange_.published().map, ++global_version_);
}

void AgentNode::Publish(MapKind kind, const LandmarkMap& map, std::uint32_t version) {
  MapMessage msg;
  msg.robot_id = self_;
  msg.kind = kind;
  msg.incarnation = incarnation_;
  msg.version = version;
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
    return;
  }
  ++stats_.maps_sent;
  stats_.bytes_sent += WireBytes(msg);
  stats_.landmarks_sent += landmarks;
  stats_.payload_bytes_sent += msg.payload.size();
  out_.PublishMap(msg);
}

void AgentNode::OnLinks(const RadioLinks& links) {
  gate_.UpdateLinks(links, sync_.processed_until());
  stats_.links_refused = gate_.links_refused();
}

double AgentNode::Clock() const { return std::max(sync_.processed_until(), gate_.links_stamp()); }

void AgentNode::OnMap(const MapMessage& msg) {
  // Our own publications echo back; an earlier incarnation of ours comes from the checkpoint.
  if (msg.robot_id == self_) return;
  if (!InRun(msg.robot_id)) {
    ++stats_.maps_unknown_sender;
    return;
  }
  const double now = Clock();
  auto refuse = [this](MapRefusal r) { ++stats_.maps_refused[static_cast<int>(r)]; };
  if (!std::isfinite(msg.stamp) || !std::isfinite(msg.origin_stamp) || msg.stamp > now + options_.max_stamp_jump_s) {
    return refuse(MapRefusal::kImplausibleStamp);
  }
  switch (gate_.Admit(msg.robot_id, WireBytes(msg), msg.stamp)) {
    case GateVerdict::kOutOfRange: ++stats_.maps_out_of_range; return;
    case GateVerdict::kLost: ++stats_.maps_lost; return;
    case GateVerdict::kBusy: ++stats_.maps_over_bandwidth; return;
    case GateVerdict::kPass: break;
  }
  stats_.bytes_received += WireBytes(msg);
  // A map larger than we will align is refused before it is decoded (kept within the codec's
  // own limit, so that a malformed count is still reported as such).
  if (const auto n = MapPayloadCount(msg.payload); n && *n <= kMapCodecMaxLandmarks && *n > peer_limits_.max_landmarks) {
    return refuse(MapRefusal::kTooManyLandmarks);
  }
  MapDecodeResult decoded = DecodeMap(msg.payload);
  if (!decoded.ok()) {
    ++stats_.maps_rejected[static_cast<int>(decoded.error)];
    return;
  }
  switch (CheckMapLimits(decoded.map, peer_limits_)) {
    case MapLimitViolation::kNone: break;
    case MapLimitViolation::kTooManyLandmarks: return refuse(MapRefusal::kTooManyLandmarks);
    case MapLimitViolation::kOutOfWorld: return refuse(MapRefusal::kOutOfWorld);
    case MapLimitViolation::kCovarianceTooLarge: return refuse(MapRefusal::kCovarianceTooLarge);
  }
  switch (exchange_.OnPeerMap(msg.robot_id, msg.incarnation, msg.kind, msg.version, msg.origin_stamp,
                              std::move(decoded.map), now)) {
    case MapExchange::Receipt::kAccepted: break;
    case MapExchange::Receipt::kStaleVersion: ++stats_.maps_stale_version; return;
    case MapExchange::Receipt::kVersionJump: return refuse(MapRefusal::kVersionJump);
    case MapExchange::Receipt::kTooManyIncarnations: return refuse(MapRefusal::kTooManyIncarnations);
  }
  ++stats_.maps_received;
  ++stats_.maps_received_from[msg.robot_id];
}

bool AgentNode::InRun(RobotId robot) const {
  return std::find(robot_ids_.begin(), robot_ids_.end(), robot) != robot_ids_.end();
}

bool AgentNode::OnPeerLiveliness(RobotId robot, bool alive) {
  if (robot == self_ || !InRun(robot)) return false;
  exchange_.OnPeerLiveliness(robot, alive, sync_.processed_until());
  return true;
}

void AgentNode::Resume(const AgentCheckpoint& c) {
  const auto add = [this](const IncarnationSnapshot& s) {
    MAPMESH_CHECK(s.robot == self_ && s.incarnation != incarnation_, "a checkpoint not validated by io::LoadCheckpoint");
    exchange_.AddOwnCheckpoint(s.incarnation, s.origin_stamp, s.local, s.global);
  };
  add(c);
  for (const IncarnationSnapshot& e : c.earlier) add(e);
}

AgentCheckpoint AgentNode::Checkpoint(std::size_t* left_out) const {
  AgentCheckpoint c;
  c.robot = self_;
  c.incarnation = incarnation_;
  c.origin_stamp = sync_.frame_origin_stamp().value_or(0.0);
  c.processed_until = sync_.processed_until();
  c.local = mapper_->Map();
  c.global = exchange_.global().map;
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
  return s;
}

}  // namespace mapmesh
