#pragma once
// The simulated world: its landmarks (given in the scenario or generated from its seed) and,
// for a park, the footpaths that the trees line and that robots may walk.

#include <Eigen/Core>
#include <cstddef>
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

// What a generator did: the work of its minimum-spacing test.
struct GenerationStats {
  long attempts = 0;         // candidate points tested against the spacing
  long distance_checks = 0;  // distances computed to accepted points (the test's cost)
  std::size_t cells = 0;     // occupied cells of the spacing grid
};

// The generators test candidates against a grid of the accepted points, so a test costs a few
// distances whatever the spacing; they give up (nullopt) after 1000 candidates per landmark
// (plus 1000), at most max(2,000,000, 50 per landmark). stats, if given, receives their work.

// Uniform random landmarks with a minimum spacing (thesis 4.1.1), by rejection sampling on
// a grid. Returns nullopt if the spacing cannot be met after many attempts.
std::optional<std::vector<Eigen::Vector2d>> GenerateUniformLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng, GenerationStats* stats = nullptr);

// Points at uniform radius and bearing in a disc (Downs's create_points: denser towards the
// centre), with the minimum spacing.
std::optional<std::vector<Eigen::Vector2d>> GenerateDiscLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng, GenerationStats* stats = nullptr);

// A park: `paths` footpaths cross the area from edge to edge, trees line both sides of them
// (at least path_width_m / 2 from any path's centre line) and scatter_fraction of the trees
// stand anywhere off the paths.
std::optional<World> GeneratePark(const LandmarkGeneratorOptions& options, std::mt19937_64& rng,
                                  GenerationStats* stats = nullptr);

// Distance from p to a polyline.
double DistanceToPolyline(const Eigen::Vector2d& p, const Polyline& line);

// The world of a simulated scenario. Throws ConfigError if generation fails.
World BuildWorld(const Scenario& scenario);

}  // namespace mapmesh
