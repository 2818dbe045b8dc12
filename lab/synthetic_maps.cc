#include "lab/synthetic_maps.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "sim_feeder/world.h"

namespace mapmesh::lab {

MapPair MakeMapPair(const MapPairOptions& o, std::mt19937_64& rng) {
  const double side = std::sqrt(o.landmarks / o.density_per_m2);
  // B's square is shifted along the diagonal so that the two share a square of `overlap`
  // of their area (as two robots' explored areas meet in a patch); a disjoint pair is set
  // two sides apart.
  const double shift = o.overlap > 0.0 ? (1.0 - std::sqrt(o.overlap)) * side : 2.0 * side;
  LandmarkGeneratorOptions g;
  g.area_m = {0.0, 0.0, side + shift, side + shift};
  g.count = static_cast<int>(std::lround(o.density_per_m2 * g.area_m.Width() * g.area_m.Height()));
  g.min_spacing_m = o.min_spacing_m;
  const auto world = GenerateUniformLandmarks(g, rng);
  MapPair pair;
  if (!world) return pair;
  std::uniform_real_distribution<double> ua(-M_PI, M_PI), ut(-100.0, 100.0);
  pair.truth = o.random_frame ? Pose2{ut(rng), ut(rng), ua(rng)} : Pose2{};
  const Pose2 to_b = pair.truth.Inverse();
  std::normal_distribution<double> n(0.0, o.sigma_m);
  const Eigen::Matrix2d cov = o.sigma_m * o.sigma_m * Eigen::Matrix2d::Identity();
  std::vector<int> world_of_b;
  for (std::size_t i = 0; i < world->size(); ++i) {
    const Eigen::Vector2d& p = (*world)[i];
    const bool in_a = p.x() <= side && p.y() <= side;
    const bool in_b = p.x() >= shift && p.y() >= shift;
    if (in_a) {
      pair.a.landmarks.push_back({static_cast<std::uint32_t>(pair.a.size()), -1, p + Eigen::Vector2d(n(rng), n(rng)),
                                  cov});
    }
    if (in_b) world_of_b.push_back(static_cast<int>(i));
  }
  // B in its own frame and in a shuffled order.
  std::shuffle(world_of_b.begin(), world_of_b.end(), rng);
  std::vector<int> a_of_world(world->size(), -1);
  for (std::size_t i = 0, k = 0; i < world->size(); ++i) {
    if ((*world)[i].x() <= side && (*world)[i].y() <= side) a_of_world[i] = static_cast<int>(k++);
  }
  for (int w : world_of_b) {
    const Eigen::Vector2d p = (*world)[w] + Eigen::Vector2d(n(rng), n(rng));
    const int ib = static_cast<int>(pair.b.size());
    pair.b.landmarks.push_back({static_cast<std::uint32_t>(ib), -1, to_b.Apply(p), cov});
    if (a_of_world[w] >= 0) pair.true_pairs.emplace_back(a_of_world[w], ib);
  }
  return pair;
}

}  // namespace mapmesh::lab
