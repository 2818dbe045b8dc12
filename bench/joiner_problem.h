#pragma once
// The joining problem the joiner benchmarks share: a chain of 50 submaps of 30 landmarks each.

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "common/slam/submap_joiner.h"

namespace mapmesh::bench {

constexpr int kJoinerSubmaps = 50;
constexpr int kJoinerLandmarksPerSubmap = 30;

// A chain of kJoinerSubmaps frames 2 m apart around a 40 m circle, each submap mapping the 30
// nearest of 300 landmarks, measured with noise of a correlated covariance.
inline std::vector<SubmapEstimate> MakeJoinerSubmaps() {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-25.0, 25.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Eigen::Vector2d> world;
  for (int i = 0; i < 300; ++i) world.emplace_back(u(rng), u(rng));
  std::vector<Pose2> frames = {{}};
  for (int k = 0; k < kJoinerSubmaps; ++k)
    frames.push_back(frames.back() * Pose2{2.0, 0.0, 2.0 * M_PI / kJoinerSubmaps * 2.0});
  std::vector<SubmapEstimate> out;
  for (int k = 0; k < kJoinerSubmaps; ++k) {
    std::vector<std::pair<double, int>> by_distance;
    for (int i = 0; i < 300; ++i) {
      by_distance.push_back({(world[i] - Eigen::Vector2d(frames[k].x, frames[k].y)).norm(), i});
    }
    std::sort(by_distance.begin(), by_distance.end());
    SubmapEstimate s;
    std::vector<Eigen::Vector2d> seen;
    for (int j = 0; j < kJoinerLandmarksPerSubmap; ++j) {
      s.keys.push_back(static_cast<std::uint32_t>(by_distance[j].second));
      seen.push_back(world[by_distance[j].second]);
    }
    std::sort(s.keys.begin(), s.keys.end());
    seen.clear();
    for (std::uint32_t key : s.keys) seen.push_back(world[key]);
    const Eigen::VectorXd h = PredictSubmap(frames[k], frames[k + 1], seen);
    const Eigen::Index n = h.size();
    Eigen::MatrixXd a = 0.02 * Eigen::MatrixXd::Identity(n, n);
    a.col(2).array() += 0.01;  // a shared heading error
    s.p = a * a.transpose();
    Eigen::VectorXd e(n);
    for (Eigen::Index i = 0; i < n; ++i) e(i) = g(rng);
    s.x = h + a * e;
    out.push_back(s);
  }
  return out;
}

}  // namespace mapmesh::bench
