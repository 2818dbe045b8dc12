#include "agent/rendezvous_tracker.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "common/slam/local_mapper.h"

namespace mapmesh {
namespace {

Eigen::Matrix3d CovOf(const Sighting& m) {
  const auto& c = m.cov;
  Eigen::Matrix3d cov;
  cov << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
  return cov;
}

void SetCov(Sighting& m, const Eigen::Matrix3d& cov) {
  m.cov = {cov(0, 0), cov(0, 1), cov(0, 2), cov(1, 1), cov(1, 2), cov(2, 2)};
}

Sighting Message(RobotId self, std::uint32_t incarnation, double stamp, const Pose2& pose, const Eigen::Matrix3d& cov) {
  Sighting m;
  m.robot_id = self;
  m.incarnation = incarnation;
  m.stamp = stamp;
  m.x = pose.x;
  m.y = pose.y;
  m.theta = pose.theta;
  SetCov(m, cov);
  return m;
}

PointEstimate PositionOf(const Pose2& pose, const Eigen::Matrix3d& cov) {
  return {Eigen::Vector2d(pose.x, pose.y), cov.topLeftCorner<2, 2>()};
}

}  // namespace

bool SightingWellFormed(const Sighting& m) {
  const double values[] = {m.stamp, m.x, m.y, m.theta, m.range, m.bearing, m.sigma_range, m.sigma_bearing};
  for (double v : values) {
    if (!std::isfinite(v)) return false;
  }
  const Eigen::Matrix3d cov = CovOf(m);
  if (!cov.allFinite()) return false;
  const Eigen::LLT<Eigen::Matrix3d> llt(cov);
  if (llt.info() != Eigen::Success) return false;
  if (m.kind == SightingKind::kSighting && (m.range < 0 || !(m.sigma_range > 0) || !(m.sigma_bearing > 0)))
    return false;
  return true;
}

RendezvousTracker::RendezvousTracker(RobotId self, std::uint32_t incarnation, std::vector<RobotId> robots,
                                     const RendezvousOptions& options, double sigma_range_m, double sigma_bearing_rad)
    : self_(self),
      incarnation_(incarnation),
      robots_(std::move(robots)),
      options_(options),
      sigma_range_(sigma_range_m),
      sigma_bearing_(sigma_bearing_rad) {}

bool RendezvousTracker::InRun(RobotId r) const {
  return r != self_ && std::find(robots_.begin(), robots_.end(), r) != robots_.end();
}

void RendezvousTracker::Forget(double now) {
  const double horizon = now - options_.window_s;
  while (!poses_.empty() && poses_.front().t < horizon) poses_.pop_front();
  while (!own_.empty() && own_.front().t < horizon) own_.pop_front();
}

void RendezvousTracker::OnPose(double stamp, const Pose2& pose, const Eigen::Matrix3d& cov) {
  if (!poses_.empty() && stamp < poses_.back().t) return;
  if (!poses_.empty() && stamp == poses_.back().t) {
    poses_.back() = {stamp, pose, cov};
  } else {
    poses_.push_back({stamp, pose, cov});
  }
  now_ = std::max(now_, stamp);
  Forget(now_);
}

bool RendezvousTracker::PoseAtStamp(double t, PoseAt* out) const {
  auto it = std::lower_bound(poses_.begin(), poses_.end(), t, [](const PoseAt& p, double v) { return p.t < v; });
  if (it != poses_.end() && std::abs(it->t - t) < 1e-9) {
    *out = *it;
    return true;
  }
  if (it == poses_.end() || it == poses_.begin()) return false;
  const PoseAt& b = *it;
  const PoseAt& a = *(it - 1);
  if (b.t - a.t > options_.max_pose_gap_s) return false;
  const double f = (t - a.t) / (b.t - a.t);
  out->t = t;
  out->pose = Interpolate(a.pose, b.pose, f);
  out->cov = (1 - f) * a.cov + f * b.cov;
  return true;
}

std::vector<Sighting> RendezvousTracker::OnScan(const std::vector<Observation>& obs, double stamp, const Pose2& pose,
                                                const Eigen::Matrix3d& cov) {
  std::vector<Sighting> out;
  for (const Observation& o : obs) {
    if (o.kind != ObservationKind::kRobot || o.signature < 0 || !IsValidObservation(o)) continue;
    const RobotId peer = static_cast<RobotId>(o.signature);
    if (!InRun(peer)) continue;
    const auto last = last_sent_.find(peer);
    if (last != last_sent_.end() && stamp - last->second < options_.period_s - 1e-9) continue;
    last_sent_[peer] = stamp;
    own_.push_back({stamp, peer, o.range, o.bearing, pose, cov});
    Sighting m = Message(self_, incarnation_, stamp, pose, cov);
    m.kind = SightingKind::kSighting;
    m.other = peer;
    m.range = o.range;
    m.bearing = o.bearing;
    m.sigma_range = sigma_range_;
    m.sigma_bearing = sigma_bearing_;
    out.push_back(m);
    ++stats_.sightings_sent;
  }
  return out;
}

void RendezvousTracker::OnMessage(const Sighting& m) {
  if (m.robot_id == self_ || !InRun(m.robot_id) || m.other != self_) return;
  if (!SightingWellFormed(m)) {
    ++stats_.refused;
    return;
  }
  const PeerKey key{m.robot_id, m.incarnation};
  if (m.kind == SightingKind::kSighting) {
    pending_.push_back(m);
    if (static_cast<int>(pending_.size()) > options_.max_pending) pending_.pop_front();
    return;
  }
  // An answer to one of our sightings: the peer's own position then, in its frame.
  if (m.other_incarnation != incarnation_) return;
  const auto mine = std::find_if(own_.begin(), own_.end(), [&](const OwnSighting& s) {
    return s.peer == m.robot_id && std::abs(s.t - m.stamp) < 1e-9;
  });
  if (mine == own_.end()) {
    ++stats_.unmatched;
    return;
  }
  const auto seen = SightedPosition(mine->pose, mine->cov, mine->range, mine->bearing, sigma_range_, sigma_bearing_);
  if (!seen) return;
  SightingPair p;
  p.stamp = m.stamp;
  p.own = *seen;
  p.peer = PositionOf({m.x, m.y, m.theta}, CovOf(m));
  AddPair(key, p);
  ++stats_.answers_used;
}

RendezvousTracker::Frame& RendezvousTracker::FrameOf(const PeerKey& key, double now) {
  auto it = frames_.find(key);
  if (it == frames_.end()) {
    // Bounded: a robot's frames beyond the limit evict the one updated least recently.
    std::vector<std::map<PeerKey, Frame>::iterator> same;
    for (auto f = frames_.lower_bound({key.robot, 0}); f != frames_.end() && f->first.robot == key.robot; ++f)
      same.push_back(f);
    if (static_cast<int>(same.size()) >= options_.max_frames_per_robot) {
      frames_.erase(*std::min_element(same.begin(), same.end(), [](const auto& a, const auto& b) {
        return a->second.updated < b->second.updated;
      }));
    }
    it = frames_.emplace(key, Frame{}).first;
  }
  it->second.updated = now;
  it->second.fresh = true;
  return it->second;
}

void RendezvousTracker::AddPair(const PeerKey& key, const SightingPair& p) {
  Frame& f = FrameOf(key, now_);
  f.pairs.push_back(p);
  if (static_cast<int>(f.pairs.size()) > options_.max_pairs) f.pairs.pop_front();
}

std::vector<Sighting> RendezvousTracker::Advance(double now) {
  now_ = std::max(now_, now);
  std::vector<Sighting> out;
  std::deque<Sighting> waiting;
  for (const Sighting& m : pending_) {
    if (m.stamp > now + 1e-9) {
      waiting.push_back(m);
      continue;
    }
    PoseAt mine;
    if (!PoseAtStamp(m.stamp, &mine)) {
      ++stats_.unmatched;
      continue;
    }
    const PeerKey key{m.robot_id, m.incarnation};
    const Pose2 theirs{m.x, m.y, m.theta};
    const auto seen = SightedPosition(theirs, CovOf(m), m.range, m.bearing, m.sigma_range, m.sigma_bearing);
    if (!seen) continue;
    SightingPair p;
    p.stamp = m.stamp;
    p.own = PositionOf(mine.pose, mine.cov);
    p.peer = *seen;
    AddPair(key, p);
    ++stats_.sightings_used;
    // Did we see it too, at about the same time? Then the two sightings fix the whole transform.
    for (const OwnSighting& s : own_) {
      if (s.peer != m.robot_id || std::abs(s.t - m.stamp) > options_.mutual_within_s) continue;
      RendezvousInput in;
      in.pose1 = s.pose;
      in.cov1 = s.cov;
      in.pose2 = theirs;
      in.cov2 = CovOf(m);
      in.range12 = s.range;
      in.bearing12 = s.bearing;
      in.range21 = m.range;
      in.bearing21 = m.bearing;
      in.sigma_range1 = sigma_range_;
      in.sigma_bearing1 = sigma_bearing_;
      in.sigma_range2 = m.sigma_range;
      in.sigma_bearing2 = m.sigma_bearing;
      if (const auto r = RendezvousAlign(in)) {
        Frame& f = FrameOf(key, now_);
        f.mutual.push_back(*r);
        if (static_cast<int>(f.mutual.size()) > options_.max_mutual) f.mutual.pop_front();
        ++stats_.mutual;
      }
      break;
    }
    Sighting answer = Message(self_, incarnation_, m.stamp, mine.pose, mine.cov);
    answer.kind = SightingKind::kAnswer;
    answer.other = m.robot_id;
    answer.other_incarnation = m.incarnation;
    out.push_back(answer);
    ++stats_.answers_sent;
  }
  pending_ = std::move(waiting);
  return out;
}

std::vector<std::pair<PeerKey, RendezvousFit>> RendezvousTracker::TakeFits() {
  std::vector<std::pair<PeerKey, RendezvousFit>> out;
  for (auto& [key, f] : frames_) {
    if (!f.fresh) continue;
    f.fresh = false;
    const std::vector<SightingPair> pairs(f.pairs.begin(), f.pairs.end());
    const std::vector<RendezvousResult> mutual(f.mutual.begin(), f.mutual.end());
    RendezvousFit fit = FitRendezvous(pairs, mutual, options_.fit);
    ++stats_.fits;
    stats_.fits_accepted += fit.accepted();
    out.emplace_back(key, std::move(fit));
  }
  return out;
}

}  // namespace mapmesh
