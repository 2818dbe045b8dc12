#pragma once
// The simulated world's landmarks: given in the scenario or generated from a seed.

#include <Eigen/Core>
#include <optional>
#include <random>
#include <vector>

#include "common/config/scenario.h"

namespace mapmesh {

// Uniform random landmarks with a minimum spacing (thesis 4.1.1), by rejection sampling on
// a grid. Returns nullopt if the spacing cannot be met after many attempts.
std::optional<std::vector<Eigen::Vector2d>> GenerateUniformLandmarks(
    const LandmarkGeneratorOptions& options, std::mt19937_64& rng);

// The landmarks of a scenario: its list or CSV, or its generator seeded from the scenario.
// Throws ConfigError if generation fails.
std::vector<Eigen::Vector2d> BuildLandmarks(const Scenario& scenario);

}  // namespace mapmesh
