#include "sim_feeder/world.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>

#include "common/config/config_error.h"

namespace mapmesh {
namespace {

// Accepts points at least `spacing` from every accepted point. A hash grid holds them: its cells
// are at least `spacing` wide, so a point's rivals lie in the 3 x 3 cells around its own, and at
// least sqrt(area / count) wide, so that a spacing far below the landmarks' mean distance still
// leaves about one landmark per cell. A test then computes a few distances, never one to every
// accepted point (as when a tiny spacing's huge cell indices were cast into a single cell).
class SpacedSet {
 public:
  SpacedSet(double spacing, const Rect& area, int count, GenerationStats* stats)
      : d_(spacing), origin_(area.xmin, area.ymin), stats_(stats ? stats : &own_stats_) {
    const double per_point = std::sqrt(std::max(area.Width() * area.Height(), 0.0) / std::max(count, 1));
    cell_ = std::max(d_, per_point);
    if (!(cell_ > 0.0) || !std::isfinite(cell_)) cell_ = 1.0;
  }
  SpacedSet(const SpacedSet&) = delete;
  SpacedSet& operator=(const SpacedSet&) = delete;
  bool TryAdd(const Eigen::Vector2d& p) {
    ++stats_->attempts;
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
          ++stats_->distance_checks;
          if ((pts_[j] - p).norm() < d_) return false;
        }
      }
    }
    grid_[Key(cx, cy)].push_back(static_cast<int>(pts_.size()));
    stats_->cells = grid_.size();
    pts_.push_back(p);
    return true;
  }
  std::size_t size() const { return pts_.size(); }
  std::vector<Eigen::Vector2d> Take() { return std::move(pts_); }

 private:
  // Cell indices are clamped before the cast (a double out of int64's range has no defined
  // cast); points beyond the clamp share the edge cells, which stays correct, only slower.
  static std::int64_t CellIndex(double offset, double cell) {
    constexpr double kMaxIndex = 1 << 30;
    return static_cast<std::int64_t>(std::clamp(std::floor(offset / cell), -kMaxIndex, kMaxIndex));
  }
  std::pair<std::int64_t, std::int64_t> Cell(const Eigen::Vector2d& p) const {
    return {CellIndex(p.x() - origin_.x(), cell_), CellIndex(p.y() - origin_.y(), cell_)};
  }
  // Distinct for every pair of indices within the clamp.
  static std::uint64_t Key(std::int64_t x, std::int64_t y) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(x)) << 32) | static_cast<std::uint32_t>(y);
  }
  double d_;
  double cell_ = 1.0;
  Eigen::Vector2d origin_;
  GenerationStats own_stats_;
  GenerationStats* stats_;
  std::vector<Eigen::Vector2d> pts_;
  std::unordered_map<std::uint64_t, std::vector<int>> grid_;
};

// Candidates drawn before a generator gives up: 1000 per landmark (plus 1000), but no more
// than 50 per landmark or 2,000,000, whichever is more. The cap leaves worlds of up to 1999
// landmarks as they always were, and keeps a jammed park path or a world the paths cover from
// taking minutes; near the jam limit of the load check uniform placement needs a few per landmark.
long MaxAttempts(int count) {
  const long legacy = 1000L * count + 1000;
  return std::min(legacy, std::max(2000000L, 50L * count));
}

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

std::optional<std::vector<Eigen::Vector2d>> GenerateUniformLandmarks(const LandmarkGeneratorOptions& options,
                                                                     std::mt19937_64& rng, GenerationStats* stats) {
  const Rect& a = options.area_m;
  std::uniform_real_distribution<double> ux(a.xmin, a.xmax), uy(a.ymin, a.ymax);
  SpacedSet set(options.min_spacing_m, a, options.count, stats);
  for (long k = 0; k < MaxAttempts(options.count) && static_cast<int>(set.size()) < options.count; ++k) {
    const double x = ux(rng);
    set.TryAdd({x, uy(rng)});
  }
  if (static_cast<int>(set.size()) < options.count) return std::nullopt;
  return set.Take();
}

std::optional<std::vector<Eigen::Vector2d>> GenerateDiscLandmarks(const LandmarkGeneratorOptions& options,
                                                                  std::mt19937_64& rng, GenerationStats* stats) {
  std::uniform_real_distribution<double> ur(0.0, options.radius_m), ub(0.0, 2.0 * std::numbers::pi);
  const Eigen::Vector2d& c = options.center_m;
  const double radius = options.radius_m;
  SpacedSet set(options.min_spacing_m, Rect{c.x() - radius, c.y() - radius, c.x() + radius, c.y() + radius},
                options.count, stats);
  for (long k = 0; k < MaxAttempts(options.count) && static_cast<int>(set.size()) < options.count; ++k) {
    const double r = ur(rng), b = ub(rng);
    set.TryAdd(options.center_m + r * Eigen::Vector2d(std::cos(b), std::sin(b)));
  }
  if (static_cast<int>(set.size()) < options.count) return std::nullopt;
  return set.Take();
}

std::optional<World> GeneratePark(const LandmarkGeneratorOptions& o, std::mt19937_64& rng, GenerationStats* stats) {
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
  SpacedSet set(o.min_spacing_m, a, o.count, stats);
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
  if (g.type == LandmarkLayout::kPark) {
    world = GeneratePark(g, rng);
  } else {
    auto pts = g.type == LandmarkLayout::kDisc ? GenerateDiscLandmarks(g, rng) : GenerateUniformLandmarks(g, rng);
    if (pts) world = World{std::move(*pts), {}};
  }
  if (!world) {
    throw ConfigError(scenario.path + ": world.landmarks.generator: could not place " + std::to_string(g.count) +
                      " landmarks at the minimum spacing");
  }
  for (const RobotSpec& r : scenario.robots) {
    if (r.path.type == PathType::kPark && world->paths.empty()) {
      throw ConfigError(scenario.path + ": robots: robot " + std::to_string(r.id) +
                        " has path type park but the world is not a park");
    }
  }
  return *world;
}

}  // namespace mapmesh
