#include "sim_feeder/radio_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/types/keyed_draw.h"

namespace mapmesh {

namespace {

std::uint64_t Key(std::uint64_t seed, std::uint64_t stream, RobotId a, RobotId b, std::int64_t index) {
  return DrawKey(seed, {stream, static_cast<std::uint64_t>(a), static_cast<std::uint64_t>(b),
                        static_cast<std::uint64_t>(index)});
}

double Cross(const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); }

// Whether segments p-q and a-b share a point.
bool Intersect(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const double d1 = Cross(q - p, a - p), d2 = Cross(q - p, b - p);
  const double d3 = Cross(b - a, p - a), d4 = Cross(b - a, q - a);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  auto on = [](const Eigen::Vector2d& s, const Eigen::Vector2d& t, const Eigen::Vector2d& x, double d) {
    return d == 0.0 && std::min(s.x(), t.x()) <= x.x() && x.x() <= std::max(s.x(), t.x()) &&
           std::min(s.y(), t.y()) <= x.y() && x.y() <= std::max(s.y(), t.y());
  };
  return on(p, q, a, d1) || on(p, q, b, d2) || on(a, b, p, d3) || on(a, b, q, d4);
}

double Phi(double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); }

void SortLinks(std::vector<Link>& links) {
  std::sort(links.begin(), links.end(),
            [](const Link& a, const Link& b) { return a.a != b.a ? a.a < b.a : a.b < b.b; });
}

}  // namespace

std::vector<Link> LinksInRange(const std::vector<RobotPosition>& robots, double range_m) {
  std::vector<Link> links;
  if (range_m <= 0.0) return links;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    for (std::size_t j = i + 1; j < robots.size(); ++j) {
      const double dx = robots[i].x - robots[j].x, dy = robots[i].y - robots[j].y;
      if (dx * dx + dy * dy <= range_m * range_m) {
        links.push_back({std::min(robots[i].id, robots[j].id), std::max(robots[i].id, robots[j].id)});
      }
    }
  }
  SortLinks(links);
  return links;
}

int WallsCrossed(const std::vector<RadioWall>& walls, const Eigen::Vector2d& p, const Eigen::Vector2d& q) {
  int n = 0;
  for (const RadioWall& w : walls) n += Intersect(p, q, w.a, w.b) ? 1 : 0;
  return n;
}

double RadioModel::Margin(double distance_m, int walls) const {
  const double open = distance_m <= 0.0
                          ? std::numeric_limits<double>::infinity()
                          : -10.0 * options_.path_loss_exponent * std::log10(distance_m / options_.range_m);
  return open - walls * options_.wall_loss_db;
}

double RadioModel::UpProbability(double distance_m, int walls) const {
  if (options_.range_m <= 0.0) return 0.0;
  if (options_.model == RadioModelKind::kDisc) return distance_m <= options_.range_m && walls == 0 ? 1.0 : 0.0;
  const double m = Margin(distance_m, walls);
  const double spread = std::hypot(options_.shadowing_sigma_db, options_.packet_error_width_db);
  if (spread == 0.0) return m >= 0.0 ? 1.0 : 0.0;
  return Phi(m / spread);
}

bool RadioModel::Up(RobotId a, RobotId b, double distance_m, int walls, double stamp) const {
  const double m = Margin(distance_m, walls);
  if (std::isinf(m)) return m > 0.0;
  const auto period = static_cast<std::int64_t>(std::floor(stamp / options_.shadowing_period_s));
  const double shadow = options_.shadowing_sigma_db == 0.0
                            ? 0.0
                            : options_.shadowing_sigma_db * NormalDraw(Key(seed_, 1, a, b, period));
  const double packet = options_.packet_error_width_db == 0.0
                            ? 0.0
                            : options_.packet_error_width_db *
                                  NormalDraw(Key(seed_, 2, a, b, std::llround(stamp * 1000.0)));
  return m + shadow + packet >= 0.0;
}

std::vector<Link> RadioModel::Links(const std::vector<RobotPosition>& robots, double stamp) const {
  if (options_.model == RadioModelKind::kDisc && options_.walls.empty()) return LinksInRange(robots, options_.range_m);
  std::vector<Link> links;
  if (options_.range_m <= 0.0) return links;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    for (std::size_t j = i + 1; j < robots.size(); ++j) {
      const Eigen::Vector2d p(robots[i].x, robots[i].y), q(robots[j].x, robots[j].y);
      const double d = (p - q).norm();
      const RobotId a = std::min(robots[i].id, robots[j].id), b = std::max(robots[i].id, robots[j].id);
      bool up;
      if (options_.model == RadioModelKind::kDisc) {
        up = d <= options_.range_m && WallsCrossed(options_.walls, p, q) == 0;
      } else {
        up = Up(a, b, d, WallsCrossed(options_.walls, p, q), stamp);
      }
      if (up) links.push_back({a, b});
    }
  }
  SortLinks(links);
  return links;
}

void LinkSpans::Add(const RadioLinks& table) {
  ++tables_;
  std::map<std::pair<RobotId, RobotId>, std::size_t> open;
  for (const Link& l : table.links) {
    const auto pair = std::make_pair(std::min(l.a, l.b), std::max(l.a, l.b));
    const auto it = open_.find(pair);
    std::size_t i;
    if (it != open_.end()) {
      i = it->second;
    } else {
      i = spans_.size();
      spans_.push_back({pair.first, pair.second, table.stamp, table.stamp});
    }
    spans_[i].end = table.stamp + period_s_;
    open[pair] = i;
  }
  open_ = std::move(open);
}

}  // namespace mapmesh
