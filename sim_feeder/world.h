#pragma once
// The simulated world: its landmarks (given in the scenario or generated from its seed) and,
// for a park, the footpaths that the trees line and that robots may walk.

#include <Eigen/Core>
#include <optional>
#include <random>
#include <vector>

#include "common/config/scenario.h"

namespace mapmesh {

using Polyline = std::vector<Eigen::Vector2d>;

struct World {
  std::vector<Eigen::Vector2d> landmarks;
  std::vector<Polyline> paths;  // park footpaths, else empty
};

// Uniform random landmarks with a minimum spacing (thesis 4.1.1), by rejection sampling on
// a grid. Returns nullopt if the spacing cannot be met after many attempts.
std::optional<std::vector<Eigen::Vector2d>> GenerateUniformLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng);

// Points at uniform radius and bearing in a disc (Downs's create_points: denser towards the
// centre), with the minimum spacing.
std::optional<std::vector<Eigen::Vector2d>> GenerateDiscLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng);

// A park: `paths` footpaths cross the area from edge to edge, trees line both sides of them
// (at least path_width_m / 2 from any path's centre line) and scatter_fraction of the trees
// stand anywhere off the paths.
std::optional<World> GeneratePark(const LandmarkGeneratorOptions& options, std::mt19937_64& rng);

// Distance from p to a polyline.
double DistanceToPolyline(const Eigen::Vector2d& p, const Polyline& line);

// The world of a simulated scenario. Throws ConfigError if generation fails.
World BuildWorld(const Scenario& scenario);

}  // namespace mapmesh
