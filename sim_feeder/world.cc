#include "sim_feeder/world.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "common/config/config_error.h"

namespace mapmesh {
namespace {

// Accepts points at least `spacing` from every accepted point (grid of cell size spacing).
class SpacedSet {
 public:
  SpacedSet(double spacing, Eigen::Vector2d origin) : d_(spacing), origin_(origin) {}
  bool TryAdd(const Eigen::Vector2d& p) {
    if (d_ <= 0.0) {
      pts_.push_back(p);
      return true;
    }
    const auto [cx, cy] = Cell(p);
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        auto it = grid_.find(Key(cx + dx, cy + dy));
        if (it == grid_.end()) continue;
        for (int j : it->second) {
          if ((pts_[j] - p).norm() < d_) return false;
        }
      }
    }
    grid_[Key(cx, cy)].push_back(static_cast<int>(pts_.size()));
    pts_.push_back(p);
    return true;
  }
  std::size_t size() const { return pts_.size(); }
  std::vector<Eigen::Vector2d> Take() { return std::move(pts_); }

 private:
  std::pair<std::int64_t, std::int64_t> Cell(const Eigen::Vector2d& p) const {
    return {static_cast<std::int64_t>(std::floor((p.x() - origin_.x()) / d_)),
            static_cast<std::int64_t>(std::floor((p.y() - origin_.y()) / d_))};
  }
  static std::int64_t Key(std::int64_t x, std::int64_t y) { return x * 2000003 + y; }
  double d_;
  Eigen::Vector2d origin_;
  std::vector<Eigen::Vector2d> pts_;
  std::unordered_map<std::int64_t, std::vector<int>> grid_;
};

long MaxAttempts(int count) { return 1000L * count + 1000; }

// A point on the rectangle's boundary at perimeter parameter u in [0, 1).
Eigen::Vector2d OnBoundary(const Rect& a, double u) {
  const double w = a.Width(), h = a.Height(), p = 2 * (w + h);
  double s = u * p;
  if (s < w) return {a.xmin + s, a.ymin};
  s -= w;
  if (s < h) return {a.xmax, a.ymin + s};
  s -= h;
  if (s < w) return {a.xmax - s, a.ymax};
  s -= w;
  return {a.xmin, a.ymax - s};
}

}  // namespace

double DistanceToPolyline(const Eigen::Vector2d& p, const Polyline& line) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d a = line[i], ab = line[i + 1] - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    best = std::min(best, (a + t * ab - p).norm());
  }
  if (line.size() == 1) best = (line[0] - p).norm();
  return best;
}

std::optional<std::vector<Eigen::Vector2d>> GenerateUniformLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng) {
  const Rect& a = options.area_m;
  std::uniform_real_distribution<double> ux(a.xmin, a.xmax), uy(a.ymin, a.ymax);
  SpacedSet set(options.min_spacing_m, {a.xmin, a.ymin});
  for (long k = 0; k < MaxAttempts(options.count) && static_cast<int>(set.size()) < options.count; ++k) {
    const double x = ux(rng);
    set.TryAdd({x, uy(rng)});
  }
  if (static_cast<int>(set.size()) < options.count) return std::nullopt;
  return set.Take();
}

std::optional<std::vector<Eigen::Vector2d>> GenerateDiscLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ur(0.0, options.radius_m), ub(0.0, 2.0 * std::numbers::pi);
  SpacedSet set(options.min_spacing_m, options.center_m - Eigen::Vector2d::Constant(options.radius_m));
  for (long k = 0; k < MaxAttempts(options.count) && static_cast<int>(set.size()) < options.count; ++k) {
    const double r = ur(rng), b = ub(rng);
    set.TryAdd(options.center_m + r * Eigen::Vector2d(std::cos(b), std::sin(b)));
  }
  if (static_cast<int>(set.size()) < options.count) return std::nullopt;
  return set.Take();
}

std::optional<World> GeneratePark(const LandmarkGeneratorOptions& o, std::mt19937_64& rng) {
  const Rect& a = o.area_m;
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01(0.0, 1.0);
  World world;
  // Footpaths: from one edge to a point on a different part of the boundary, bent at three
  // jittered interior points.
  for (int p = 0; p < o.paths; ++p) {
    const double u0 = u01(rng);
    const double u1 = std::fmod(u0 + 0.3 + 0.4 * u01(rng), 1.0);
    const Eigen::Vector2d s = OnBoundary(a, u0), e = OnBoundary(a, u1);
    const Eigen::Vector2d dir = e - s, normal(-dir.y(), dir.x());
    Polyline line{s};
    for (int k = 1; k <= 3; ++k) {
      Eigen::Vector2d q = s + dir * (k / 4.0) + normal * (0.12 * (u01(rng) - 0.5) * 2.0);
      q.x() = std::clamp(q.x(), a.xmin, a.xmax);
      q.y() = std::clamp(q.y(), a.ymin, a.ymax);
      line.push_back(q);
    }
    line.push_back(e);
    world.paths.push_back(line);
  }
  std::vector<double> lengths;
  double total = 0.0;
  for (const Polyline& l : world.paths) {
    for (std::size_t i = 0; i + 1 < l.size(); ++i) {
      lengths.push_back((l[i + 1] - l[i]).norm());
      total += lengths.back();
    }
  }
  auto off_paths = [&](const Eigen::Vector2d& q) {
    if (!a.Contains(q)) return false;
    for (const Polyline& l : world.paths) {
      if (DistanceToPolyline(q, l) < 0.5 * o.path_width_m) return false;
    }
    return true;
  };
  SpacedSet set(o.min_spacing_m, {a.xmin, a.ymin});
  const int along = static_cast<int>(std::lround((1.0 - o.scatter_fraction) * o.count));
  for (long k = 0; k < MaxAttempts(along) && static_cast<int>(set.size()) < along; ++k) {
    // A point along a random segment (weighted by length), on a random side, near the edge.
    double s = u01(rng) * total;
    std::size_t seg = 0;
    for (const Polyline& l : world.paths) {
      for (std::size_t i = 0; i + 1 < l.size(); ++i, ++seg) {
        if (s <= lengths[seg]) {
          const Eigen::Vector2d d = (l[i + 1] - l[i]).normalized();
          const double side = u01(rng) < 0.5 ? -1.0 : 1.0;
          const double offset = 0.5 * o.path_width_m + std::abs(n01(rng)) * 0.5 * o.path_width_m;
          const Eigen::Vector2d q = l[i] + d * s + side * offset * Eigen::Vector2d(-d.y(), d.x());
          if (off_paths(q)) set.TryAdd(q);
          s = -1;
          break;
        }
        s -= lengths[seg];
      }
      if (s < 0) break;
    }
  }
  std::uniform_real_distribution<double> ux(a.xmin, a.xmax), uy(a.ymin, a.ymax);
  for (long k = 0; k < MaxAttempts(o.count) && static_cast<int>(set.size()) < o.count; ++k) {
    const double x = ux(rng);
    const Eigen::Vector2d q(x, uy(rng));
    if (off_paths(q)) set.TryAdd(q);
  }
  if (static_cast<int>(set.size()) < o.count) return std::nullopt;
  world.landmarks = set.Take();
  return world;
}

World BuildWorld(const Scenario& scenario) {
  if (!scenario.world.generator) return {scenario.world.landmarks, {}};
  const LandmarkGeneratorOptions& g = *scenario.world.generator;
  std::mt19937_64 rng(scenario.seed * 0x9E3779B97F4A7C15ULL + 17);
  std::optional<World> world;
  if (g.type == "park") {
    world = GeneratePark(g, rng);
  } else {
    auto pts = g.type == "disc" ? GenerateDiscLandmarks(g, rng) : GenerateUniformLandmarks(g, rng);
    if (pts) world = World{std::move(*pts), {}};
  }
  if (!world) {
    throw ConfigError(scenario.path + ": world.landmarks.generator: could not place " +
                      std::to_string(g.count) + " landmarks at the minimum spacing");
  }
  for (const RobotSpec& r : scenario.robots) {
    if (r.path.type == "park" && world->paths.empty()) {
      throw ConfigError(scenario.path + ": robots: robot " + std::to_string(r.id) +
                        " has path type park but the world is not a park");
    }
  }
  return *world;
}

}  // namespace mapmesh
