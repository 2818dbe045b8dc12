#pragma once
// A seeded random world for the exchange's tests (map_exchange_test, relay_policy_test): well
// spread points, and the maps robots hold of its strips, each in its own frame with
// independent noise.

#include <Eigen/Core>
#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"

namespace mapmesh::test {

// A random world (no symmetry to fool the alignment) and the maps robots hold of parts of it.
struct World {
  std::vector<Eigen::Vector2d> points;
  explicit World(int n, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 40.0);
    while (static_cast<int>(points.size()) < n) {
      const Eigen::Vector2d p(u(rng), u(rng));
      if (std::all_of(points.begin(), points.end(), [&](const auto& q) { return (q - p).norm() > 1.5; })) {
        points.push_back(p);
      }
    }
  }
  // Landmarks with x in [x0, x1), seen from `frame` (the map frame's pose in the world).
  LandmarkMap Map(double x0, double x1, const Pose2& frame, double sigma, std::mt19937_64& rng) const {
    std::normal_distribution<double> n(0.0, sigma);
    LandmarkMap m;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (points[i].x() < x0 || points[i].x() >= x1) continue;
      Landmark l;
      l.id = static_cast<std::uint32_t>(i);
      l.mean = frame.Inverse().Apply(points[i] + Eigen::Vector2d(n(rng), n(rng)));
      l.cov = sigma * sigma * Eigen::Matrix2d::Identity();
      m.landmarks.push_back(l);
    }
    m.shape_sigma_m = sigma;
    return m;
  }
  // Distance from a point of the world to the nearest true landmark.
  double Nearest(const Eigen::Vector2d& p) const {
    double best = 1e300;
    for (const auto& q : points) best = std::min(best, (q - p).norm());
    return best;
  }
  // Landmarks of `m` (in `frame`) that lie within tol of a true one with x in [x0, x1).
  int PlacedIn(const LandmarkMap& m, const Pose2& frame, double x0, double x1, double tol) const {
    int n = 0;
    for (const Landmark& l : m.landmarks) {
      const Eigen::Vector2d w = frame.Apply(l.mean);
      if (w.x() >= x0 - tol && w.x() < x1 + tol && Nearest(w) < tol) ++n;
    }
    return n;
  }
};

}  // namespace mapmesh::test
