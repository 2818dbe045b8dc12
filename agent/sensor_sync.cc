#include "agent/sensor_sync.h"

#include <algorithm>
#include <cmath>

namespace mapmesh {

SyncStats SensorSync::stats() const {
  SyncStats s = stats_;
  s.odom_received = odom_seq_.received();
  s.odometry_lost = odom_seq_.lost();
  s.odom_out_of_sequence = odom_seq_.out_of_sequence();
  s.odom_before_join = odom_seq_.first().value_or(0);
  s.scans_received = scan_seq_.received();
  s.scans_lost = scan_seq_.lost();
  s.scans_out_of_sequence = scan_seq_.out_of_sequence();
  s.scans_before_join = scan_seq_.first().value_or(0);
  return s;
}

void SensorSync::OnOdometry(const Odometry& odom) {
  const bool finite = std::isfinite(odom.stamp) && std::isfinite(odom.dt) && std::isfinite(odom.v) &&
                      std::isfinite(odom.w) && std::isfinite(odom.steering);
  if (std::find(recent_odom_.begin(), recent_odom_.end(), std::make_pair(odom.seq, odom.stamp)) != recent_odom_.end()) {
    ++stats_.odom_duplicate;  // sent again (after a stall): one of the last ones taken
    return;
  }
  if (!finite || odom.dt <= 0.0 || (has_odom_ && odom.stamp <= last_odom_stamp_)) {
    ++stats_.odom_rejected;
    return;
  }
  if (odom.stamp - odom.dt < -1e-6 || odom.stamp > options_.max_stamp_s || odom.dt > options_.max_stamp_jump_s) {
    ++stats_.odom_implausible;
    return;
  }
  if (jump_) {
    const Odometry held = *jump_;
    jump_.reset();
    const bool continues = odom.seq == held.seq + 1 &&
                           std::abs(odom.stamp - odom.dt - held.stamp) <= 1e-6 * std::max(1.0, std::abs(held.stamp));
    if (continues) {
      Accept(held);
      Accept(odom);
      return;
    }
    ++stats_.odom_implausible;  // nothing continued it
  }
  if (has_odom_ && odom.stamp - odom.dt > last_odom_stamp_ + options_.max_stamp_jump_s) {
    jump_ = odom;
    return;
  }
  Accept(odom);
}

void SensorSync::Accept(const Odometry& odom) {
  odom_seq_.Offer(odom.seq, odom.stamp);  // counted; the message is judged by its stamp alone
  has_odom_ = true;
  recent_odom_.emplace_back(odom.seq, odom.stamp);
  if (recent_odom_.size() > kRecent) recent_odom_.pop_front();
  last_odom_stamp_ = odom.stamp;
  pending_odom_.emplace(odom.stamp, odom);
  Drain();
}

void SensorSync::OnScan(const Scan& scan) {
  // Sent again (after a stall): one of the last scans received, the very same one.
  const std::pair<std::uint32_t, double> key{scan.seq, scan.stamp};
  if (std::find(recent_scans_.begin(), recent_scans_.end(), key) != recent_scans_.end()) {
    ++stats_.scans_duplicate;
    return;
  }
  recent_scans_.push_back(key);
  if (recent_scans_.size() > kRecent) recent_scans_.pop_front();
  if (!std::isfinite(scan.stamp)) {
    ++stats_.scans_rejected;
    return;
  }
  const double reach = std::max(last_odom_stamp_, jump_ ? jump_->stamp : last_odom_stamp_);
  if (scan.stamp < 0.0 || scan.stamp > options_.max_stamp_s ||
      (has_odom_ && scan.stamp > reach + options_.max_stamp_jump_s)) {
    ++stats_.scans_implausible;
    return;
  }
  scan_seq_.Offer(scan.seq, scan.stamp);  // counted; the scan is judged by its stamp alone
  // Late: its interval was processed. Until the first one is, a scan at the stream's origin (from
  // the start pose) still belongs to it.
  if (started_ && (scan.stamp < processed_until_ || (scan.stamp == processed_until_ && stats_.odom_processed > 0))) {
    ++stats_.scans_late;
    return;
  }
  pending_scans_.emplace(scan.stamp, scan);
  Drain();
}

void SensorSync::Drain() {
  while (!pending_odom_.empty()) {
    const Odometry odom = pending_odom_.begin()->second;
    if (!started_) {
      started_ = true;
      frame_origin_stamp_ = odom.stamp - odom.dt;
      if (odom.seq == 0) {
        // The very first interval of the stream: nothing can have been missed, so it is
        // processed like any other.
        processed_until_ = odom.stamp - odom.dt;
      } else {
        // Joining a running stream (a restart): this interval's scans may have been missed
        // while this process was discovering the feeder, so it only moves the robot.
        Move({odom.v, odom.w, odom.steering}, odom.dt, odom.stamp);
        processed_until_ = odom.stamp;
        pending_odom_.erase(pending_odom_.begin());
        const auto end = pending_scans_.upper_bound(odom.stamp);
        stats_.scans_before_start += static_cast<std::uint32_t>(std::distance(pending_scans_.begin(), end));
        pending_scans_.erase(pending_scans_.begin(), end);
        ++stats_.odom_processed;
        sink_.IntervalDone(odom);
        continue;
      }
    }
    const auto end = pending_scans_.upper_bound(odom.stamp);
    const auto have = static_cast<std::uint32_t>(std::distance(pending_scans_.begin(), end));
    // Scans travel on their own topic and may arrive after later odometry.
    const bool waited_long = pending_odom_.rbegin()->first - odom.stamp > kMaxScanWaitS;
    if (have < odom.scans_in_interval && !waited_long) return;
    if (have < odom.scans_in_interval) stats_.scans_missing += odom.scans_in_interval - have;
    pending_odom_.erase(pending_odom_.begin());
    ProcessInterval(odom);
    sink_.IntervalDone(odom);
  }
}

void SensorSync::Move(const OdometryControl& u, double dt, double until) {
  if (frame_fixed_) {
    sink_.Move(u, dt);
  } else {
    frame_origin_stamp_ = until;
  }
}

void SensorSync::ProcessInterval(const Odometry& odom) {
  // Odometry holds over (stamp - dt, stamp]; each scan is applied at its own time.
  const OdometryControl u{odom.v, odom.w, odom.steering};
  double t = std::max(processed_until_, odom.stamp - odom.dt);
  const auto end = pending_scans_.upper_bound(odom.stamp);
  for (auto it = pending_scans_.begin(); it != end; ++it) {
    const double ts = std::max(it->first, t);
    if (ts > t) Move(u, ts - t, ts);
    t = ts;
    ++stats_.scans_processed;
    if (it->second.obs.empty()) {
      ++stats_.scans_empty;
    } else {
      sink_.ApplyScan(it->second, ts);
      if (!frame_fixed_ && sink_.Mapped()) frame_fixed_ = true;
    }
  }
  pending_scans_.erase(pending_scans_.begin(), end);
  if (odom.stamp > t) Move(u, odom.stamp - t, odom.stamp);
  processed_until_ = odom.stamp;
  ++stats_.odom_processed;
}

}  // namespace mapmesh
