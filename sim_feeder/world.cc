#include "sim_feeder/world.h"

#include <cmath>
#include <unordered_map>

#include "common/config/config_error.h"

namespace mapmesh {

std::optional<std::vector<Eigen::Vector2d>> GenerateUniformLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng) {
  const Rect& a = options.area_m;
  std::uniform_real_distribution<double> ux(a.xmin, a.xmax), uy(a.ymin, a.ymax);
  std::vector<Eigen::Vector2d> pts;
  pts.reserve(options.count);
  const double d = options.min_spacing_m;
  if (d <= 0.0) {
    for (int i = 0; i < options.count; ++i) pts.emplace_back(ux(rng), uy(rng));
    return pts;
  }
  // Grid of cell size d: a conflicting point can only be in the 3x3 neighbouring cells.
  auto key = [&](const Eigen::Vector2d& p) {
    const auto cx = static_cast<std::int64_t>(std::floor((p.x() - a.xmin) / d));
    const auto cy = static_cast<std::int64_t>(std::floor((p.y() - a.ymin) / d));
    return std::pair<std::int64_t, std::int64_t>{cx, cy};
  };
  struct PairHash {
    std::size_t operator()(const std::pair<std::int64_t, std::int64_t>& k) const {
      return std::hash<std::int64_t>()(k.first * 1000003 + k.second);
    }
  };
  std::unordered_map<std::pair<std::int64_t, std::int64_t>, std::vector<int>, PairHash> grid;
  const long max_attempts = 1000L * options.count + 1000;
  for (long attempt = 0; attempt < max_attempts && static_cast<int>(pts.size()) < options.count;
       ++attempt) {
    const Eigen::Vector2d p(ux(rng), uy(rng));
    const auto [cx, cy] = key(p);
    bool ok = true;
    for (std::int64_t dx = -1; dx <= 1 && ok; ++dx) {
      for (std::int64_t dy = -1; dy <= 1 && ok; ++dy) {
        auto it = grid.find({cx + dx, cy + dy});
        if (it == grid.end()) continue;
        for (int j : it->second) {
          if ((pts[j] - p).norm() < d) {
            ok = false;
            break;
          }
        }
      }
    }
    if (!ok) continue;
    grid[{cx, cy}].push_back(static_cast<int>(pts.size()));
    pts.push_back(p);
  }
  if (static_cast<int>(pts.size()) < options.count) return std::nullopt;
  return pts;
}

std::vector<Eigen::Vector2d> BuildLandmarks(const Scenario& scenario) {
  if (!scenario.world.generator) return scenario.world.landmarks;
  std::mt19937_64 rng(scenario.seed * 0x9E3779B97F4A7C15ULL + 17);
  auto pts = GenerateUniformLandmarks(*scenario.world.generator, rng);
  if (!pts) {
    throw ConfigError(scenario.path + ": world.landmarks.generator: could not place " +
                      std::to_string(scenario.world.generator->count) +
                      " landmarks at the minimum spacing");
  }
  return *pts;
}

}  // namespace mapmesh
