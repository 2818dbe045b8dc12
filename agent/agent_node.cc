#include "agent/agent_node.h"

#include <algorithm>
#include <cmath>

#include "common/check.h"
#include "common/slam/dead_reckoning_mapper.h"
#include "common/slam/local_slam.h"

namespace mapmesh {
namespace {

// MapMessage fields besides the payload: robot_id, kind, version, stamp, sequence length.
constexpr std::size_t kMapMessageFixedBytes = 4 + 1 + 4 + 8 + 4;

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
  o.max_range_m = a.max_range_m;
  o.cekf.region_half_m = a.region_half_m;
  const double range = a.max_range_m > 0 ? a.max_range_m : robot->sensor.max_range_m;
  o.cekf.reach_m = a.region_reach_m > 0 ? a.region_reach_m : range + 4.0;
  return std::make_unique<LocalSlam>(noise, o);
}

std::size_t WireBytes(const MapMessage& msg) { return kMapMessageFixedBytes + msg.payload.size(); }

std::uint32_t AgentStats::MapsRejected() const {
  std::uint32_t n = 0;
  for (auto c : maps_rejected) n += c;
  return n;
}

std::uint32_t AgentStats::MapsDropped() const {
  return maps_out_of_range + maps_lost + maps_over_bandwidth + maps_unknown_sender + MapsRejected();
}

AgentNode::AgentNode(const Scenario& scenario, RobotId self, std::uint32_t incarnation,
                     AgentOutput& out)
    : options_(scenario.agent),
      self_(self),
      incarnation_(incarnation),
      out_(out),
      gate_(self, RadioGateOptions{scenario.radio.loss_probability, scenario.radio.bandwidth_bytes_per_s},
            scenario.seed * 1000003ULL + self * 7919ULL + incarnation),
      mapper_(MakeLocalMapper(scenario, self)) {
  for (const auto& r : scenario.robots) robot_ids_.push_back(r.id);
}

void AgentNode::OnOdometry(const Odometry& odom) {
  const bool finite = std::isfinite(odom.stamp) && std::isfinite(odom.dt) &&
                      std::isfinite(odom.v) && std::isfinite(odom.w) &&
                      std::isfinite(odom.steering);
  if (!finite || odom.dt <= 0.0 || (started_ && odom.stamp <= processed_until_) ||
      pending_odom_.count(odom.stamp)) {
    ++stats_.odom_rejected;
    return;
  }
  pending_odom_.emplace(odom.stamp, odom);
  Drain();
}

void AgentNode::OnScan(const Scan& scan) {
  if (!std::isfinite(scan.stamp)) {
    ++stats_.scans_rejected;
    return;
  }
  if (started_ && scan.stamp <= processed_until_) {
    ++stats_.scans_late;
    return;
  }
  pending_scans_.emplace(scan.stamp, scan);
  Drain();
}

void AgentNode::Drain() {
  while (!pending_odom_.empty()) {
    const Odometry odom = pending_odom_.begin()->second;
    if (!started_) {
      started_ = true;
      frame_origin_stamp_ = odom.stamp - odom.dt;
      if (odom.seq == 0) {
        // The very first interval of the stream: nothing can have been missed, so it is
        // processed like any other. The map frame is the pose at its start.
        processed_until_ = odom.stamp - odom.dt;
      } else {
        // Joining a running stream (a restart): this interval's scans may have been missed
        // while this process was discovering the feeder, so it only moves the pose.
        mapper_->Predict({odom.v, odom.w, odom.steering}, odom.dt);
        processed_until_ = odom.stamp;
        pending_odom_.erase(pending_odom_.begin());
        auto end = pending_scans_.upper_bound(odom.stamp);
        stats_.scans_before_start += static_cast<std::uint32_t>(std::distance(pending_scans_.begin(), end));
        pending_scans_.erase(pending_scans_.begin(), end);
        ++stats_.odom_processed;
        AfterInterval(odom);
        continue;
      }
    }
    const auto end = pending_scans_.upper_bound(odom.stamp);
    const auto have = static_cast<std::uint32_t>(std::distance(pending_scans_.begin(), end));
    // Scans travel on their own topic and may arrive after later odometry; wait for them
    // unless the queue already spans far more than a lockstep window (then they are lost).
    const bool waited_long = pending_odom_.rbegin()->first - odom.stamp > kMaxScanWaitS;
    if (have < odom.scans_in_interval && !waited_long) return;
    if (have < odom.scans_in_interval) stats_.scans_missing += odom.scans_in_interval - have;
    pending_odom_.erase(pending_odom_.begin());
    ProcessInterval(odom);
    AfterInterval(odom);
  }
}

void AgentNode::ProcessInterval(const Odometry& odom) {
  // Odometry (v, w) holds over (stamp - dt, stamp]; each scan is applied at its own time.
  const OdometryControl u{odom.v, odom.w, odom.steering};
  double t = std::max(processed_until_, odom.stamp - odom.dt);
  const auto end = pending_scans_.upper_bound(odom.stamp);
  for (auto it = pending_scans_.begin(); it != end; ++it) {
    const double ts = std::max(it->first, t);
    if (ts > t) mapper_->Predict(u, ts - t);
    t = ts;
    mapper_->Observe(it->second.obs, ts);
    ++stats_.scans_processed;
  }
  pending_scans_.erase(pending_scans_.begin(), end);
  if (odom.stamp > t) mapper_->Predict(u, odom.stamp - t);
  processed_until_ = odom.stamp;
  ++stats_.odom_processed;
}

void AgentNode::AfterInterval(const Odometry& odom) {
  if (processed_until_ + 1e-9 >= next_map_publish_s_) {
    PublishLocalMap();
    next_map_publish_s_ =
        (std::floor(processed_until_ / options_.map_publish_period_s + 1e-9) + 1.0) *
        options_.map_publish_period_s;
  }
  bool status_due = odom.sync;
  if (processed_until_ + 1e-9 >= next_status_s_) {
    status_due = true;
    next_status_s_ = (std::floor(processed_until_ / options_.status_period_s + 1e-9) + 1.0) *
                     options_.status_period_s;
  }
  if (status_due) out_.PublishStatus(Status());
}

void AgentNode::PublishLocalMap() {
  MapMessage msg;
  msg.robot_id = self_;
  msg.kind = MapKind::kLocal;
  msg.version = ++local_version_;
  msg.stamp = processed_until_;
  msg.payload = EncodeMap(mapper_->Map());
  ++stats_.maps_sent;
  stats_.bytes_sent += WireBytes(msg);
  out_.PublishMap(msg);
}

void AgentNode::OnLinks(const RadioLinks& links) { gate_.UpdateLinks(links); }

void AgentNode::OnMap(const MapMessage& msg) {
  if (msg.robot_id == self_) return;  // our own publication, echoed back
  if (std::find(robot_ids_.begin(), robot_ids_.end(), msg.robot_id) == robot_ids_.end()) {
    ++stats_.maps_unknown_sender;
    return;
  }
  switch (gate_.Admit(msg.robot_id, WireBytes(msg), msg.stamp)) {
    case GateVerdict::kOutOfRange: ++stats_.maps_out_of_range; return;
    case GateVerdict::kLost: ++stats_.maps_lost; return;
    case GateVerdict::kBusy: ++stats_.maps_over_bandwidth; return;
    case GateVerdict::kPass: break;
  }
  stats_.bytes_received += WireBytes(msg);
  MapDecodeResult decoded = DecodeMap(msg.payload);
  if (!decoded.ok()) {
    ++stats_.maps_rejected[static_cast<int>(decoded.error)];
    return;
  }
  ++stats_.maps_received;
  ++stats_.maps_received_from[msg.robot_id];
  peer_maps_[{msg.robot_id, msg.kind}] = std::move(decoded.map);
}

AgentStatus AgentNode::Status() const {
  AgentStatus s;
  s.robot_id = self_;
  s.incarnation = incarnation_;
  s.processed_until = processed_until_;
  s.odom_processed = stats_.odom_processed;
  s.scans_processed = stats_.scans_processed;
  s.local_landmarks = static_cast<std::uint32_t>(mapper_->size());
  s.global_landmarks = s.local_landmarks;
  s.maps_received = stats_.maps_received;
  s.maps_dropped = stats_.MapsDropped();
  s.bytes_sent = stats_.bytes_sent;
  s.bytes_received = stats_.bytes_received;
  return s;
}

}  // namespace mapmesh
