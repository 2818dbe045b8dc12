#pragma once
// Simulated submap chains for tests (issue J1): landmarks on a grid and robots whose submaps are
// exact Gaussian measurements of it, each with its own correlated covariance.

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <random>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/submap_codec.h"
#include "common/slam/submap_joiner.h"

namespace mapmesh::testing {

// A world of landmarks on a grid and robots whose submaps are exact Gaussian measurements of
// it: z = h(true frames, true landmarks) + L n with p = L L^T a random covariance (correlated
// across the submap's entries, as an EKF's is).
struct World {
  std::vector<Eigen::Vector2d> landmarks;
  explicit World(int side, double spacing) {
    for (int i = 0; i < side; ++i) {
      for (int j = 0; j < side; ++j) landmarks.emplace_back(i * spacing, j * spacing);
    }
  }
};

// A chain's true frames and the landmarks (indices into the world) each submap holds.
struct TrueChain {
  std::vector<Pose2> frames;           // 0 .. K in the world
  std::vector<std::vector<int>> seen;  // per submap
};

inline Eigen::MatrixXd RandomCovariance(int n, std::mt19937_64& rng, double scale) {
  std::normal_distribution<double> g;
  Eigen::MatrixXd a(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) a(i, j) = g(rng);
  }
  return scale * scale * (a * a.transpose() / n + Eigen::MatrixXd::Identity(n, n));
}

inline WireSubmap Measure(const World& w, const TrueChain& c, std::size_t k, RobotId robot, std::mt19937_64& rng) {
  std::vector<Eigen::Vector2d> points;
  for (int i : c.seen[k]) points.push_back(w.landmarks[static_cast<std::size_t>(i)]);
  const Eigen::VectorXd h = PredictSubmap(c.frames[k], c.frames[k + 1], points);
  const int n = static_cast<int>(h.size());
  WireSubmap s;
  s.id = {robot, 1, static_cast<std::uint32_t>(k)};
  s.opened_s = 10.0 * k;
  s.closed_s = 10.0 * k + 9;
  for (int i : c.seen[k]) s.keys.push_back(static_cast<std::uint32_t>(i));
  EXPECT_TRUE(s.SetCovariance(RandomCovariance(n, rng, 0.05)));
  std::normal_distribution<double> g;
  Eigen::VectorXd noise(n);
  for (int i = 0; i < n; ++i) noise(i) = g(rng);
  s.x = h + s.l * noise;  // the covariance as the wire holds it is the one the noise has
  return s;
}

// Every submap of a chain, measured.
inline std::vector<WireSubmap> MeasureAll(const World& w, const TrueChain& c, RobotId robot, std::mt19937_64& rng) {
  std::vector<WireSubmap> out;
  for (std::size_t k = 0; k < c.seen.size(); ++k) out.push_back(Measure(w, c, k, robot, rng));
  return out;
}

// A robot driving along a row of the grid: its submaps each hold the landmarks near it.
inline TrueChain Drive(const World& w, Pose2 start, int submaps, double step) {
  TrueChain c;
  c.frames.push_back(start);
  for (int k = 0; k < submaps; ++k) c.frames.push_back(c.frames.back() * Pose2{step, 0.3, 0.15});
  for (int k = 0; k < submaps; ++k) {
    std::vector<int> seen;
    for (std::size_t i = 0; i < w.landmarks.size(); ++i) {
      const Eigen::Vector2d mid = 0.5 * (Eigen::Vector2d(c.frames[k].x, c.frames[k].y) +
                                         Eigen::Vector2d(c.frames[k + 1].x, c.frames[k + 1].y));
      if ((w.landmarks[i] - mid).norm() < 6.0) seen.push_back(static_cast<int>(i));
    }
    c.seen.push_back(seen);
  }
  return c;
}

// The submaps as a chain (pointers into them).
inline std::vector<const WireSubmap*> Pointers(const std::vector<WireSubmap>& submaps) {
  std::vector<const WireSubmap*> out;
  for (const WireSubmap& s : submaps) out.push_back(&s);
  return out;
}

}  // namespace mapmesh::testing
