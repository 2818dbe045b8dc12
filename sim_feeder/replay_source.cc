#include "sim_feeder/replay_source.h"

#include <algorithm>
#include <limits>

#include "common/metrics/trajectory_metrics.h"
#include "sim_feeder/radio_model.h"

namespace mapmesh {

void CountScansPerInterval(RobotStreams& r) {
  std::size_t s = 0;
  for (Odometry& o : r.odom) {
    const double start = o.stamp - o.dt;
    while (s < r.scans.size() && r.scans[s].stamp <= start) ++s;  // before this interval
    std::uint32_t n = 0;
    while (s < r.scans.size() && r.scans[s].stamp <= o.stamp) {
      ++n;
      ++s;
    }
    o.scans_in_interval = n;
  }
}

void Truncate(ReplayData& data, double duration_s) {
  auto after = [duration_s](double t) { return t > duration_s + 1e-9; };
  for (RobotStreams& r : data.robots) {
    std::erase_if(r.odom, [&](const Odometry& o) { return after(o.stamp); });
    std::erase_if(r.scans, [&](const Scan& s) { return after(s.stamp); });
    std::erase_if(r.truth, [&](const GroundTruth& g) { return after(g.stamp); });
    CountScansPerInterval(r);
  }
  data.duration_s = std::min(data.duration_s, duration_s);
}

ReplaySource::ReplaySource(ReplayData data, const RadioOptions& radio, std::uint64_t seed)
    : data_(std::move(data)), radio_(radio), radio_model_(radio, seed), cursors_(data_.robots.size()) {
  truth_.landmarks = data_.landmarks;
  truth_.seen = data_.seen;
  truth_.headings_known = data_.headings_known;
  for (const RobotStreams& r : data_.robots) {
    if (r.start) truth_.starts.emplace_back(r.id, *r.start);
  }
}

double ReplaySource::NextStamp() const {
  double t = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < data_.robots.size(); ++i) {
    const RobotStreams& r = data_.robots[i];
    const Cursor& c = cursors_[i];
    if (c.odom < r.odom.size()) t = std::min(t, r.odom[c.odom].stamp);
    if (c.scan < r.scans.size()) t = std::min(t, r.scans[c.scan].stamp);
    if (c.truth < r.truth.size()) t = std::min(t, r.truth[c.truth].stamp);
  }
  if (std::isfinite(t) && next_links_s_ <= data_.duration_s) t = std::min(t, next_links_s_);
  return t;
}

bool ReplaySource::Done() const { return !std::isfinite(NextStamp()); }

std::optional<Eigen::Vector2d> ReplaySource::PositionAt(const RobotStreams& r, double t) const {
  const std::optional<Pose2> p = TruthAt(r.truth, t);
  if (!p) return std::nullopt;
  return Eigen::Vector2d(p->x, p->y);
}

FeedBatch ReplaySource::Next() {
  FeedBatch b;
  b.stamp = NextStamp();
  for (std::size_t i = 0; i < data_.robots.size(); ++i) {
    const RobotStreams& r = data_.robots[i];
    Cursor& c = cursors_[i];
    while (c.scan < r.scans.size() && r.scans[c.scan].stamp == b.stamp) b.scans.push_back(r.scans[c.scan++]);
    while (c.odom < r.odom.size() && r.odom[c.odom].stamp == b.stamp) b.odom.push_back(r.odom[c.odom++]);
    while (c.truth < r.truth.size() && r.truth[c.truth].stamp == b.stamp) b.truth.push_back(r.truth[c.truth++]);
  }
  if (b.stamp >= next_links_s_) {
    // Links from true positions; robots without ground truth are assumed within range of all.
    std::vector<RobotPosition> known;
    std::vector<RobotId> unknown;
    for (const RobotStreams& r : data_.robots) {
      if (auto p = PositionAt(r, b.stamp)) {
        known.push_back({r.id, p->x(), p->y()});
      } else {
        unknown.push_back(r.id);
      }
    }
    RadioLinks links{b.stamp, radio_model_.Links(known, b.stamp)};
    if (radio_.range_m > 0.0) {
      for (RobotId u : unknown) {
        for (const RobotStreams& r : data_.robots) {
          if (r.id != u && (r.id > u || std::find(unknown.begin(), unknown.end(), r.id) == unknown.end())) {
            links.links.push_back({std::min(u, r.id), std::max(u, r.id)});
          }
        }
      }
      std::sort(links.links.begin(), links.links.end(),
                [](const Link& x, const Link& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
    }
    b.links = std::move(links);
    while (next_links_s_ <= b.stamp) next_links_s_ += radio_.links_period_s;
  }
  return b;
}

}  // namespace mapmesh
