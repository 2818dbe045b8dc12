#pragma once
// Synthetic map pairs for alignment experiments: two robots' maps cut from one random world,
// sharing a square patch of landmarks, with independent noise, the second seen in a random
// frame.

#include <random>
#include <utility>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"

namespace mapmesh::lab {

struct MapPair {
  LandmarkMap a, b;
  Pose2 truth;                                  // maps B's frame into A's
  std::vector<std::pair<int, int>> true_pairs;  // (index in A, index in B) of shared landmarks
};

struct MapPairOptions {
  int landmarks = 1000;  // per map (about)
  double overlap = 0.1;  // share of each map's area (and landmarks) the other also has; 0: disjoint
  double sigma_m = 0.1;  // noise on every landmark mean, per map; covariances sigma^2 I
  double density_per_m2 = 0.25;
  double min_spacing_m = 1.0;
  bool random_frame = true;  // B in a random frame (rotation anywhere, translation within 100 m)
};

MapPair MakeMapPair(const MapPairOptions& options, std::mt19937_64& rng);

}  // namespace mapmesh::lab
