#include "common/merge/map_joining.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <map>
#include <tuple>
#include <vector>

#include "common/solver/least_squares.h"

namespace mapmesh {
namespace {

struct Observed {
  int landmark;  // global index
  int source;    // -1: the own map
  Eigen::Vector2d z;
  Eigen::Matrix2d w;       // information
  Eigen::Matrix2d sqrt_w;  // S with S^T S = w: whitens the residual
  double weight = 1.0;     // the robust kernel's weight at the last estimate
};

bool Information(const Eigen::Matrix2d& cov, Eigen::Matrix2d* w) {
  if (!cov.allFinite()) return false;
  const Eigen::LLT<Eigen::Matrix2d> llt(cov);
  if (llt.info() != Eigen::Success) return false;
  *w = llt.solve(Eigen::Matrix2d::Identity());
  return w->allFinite();
}

}  // namespace

GlobalMap JoinMaps(const LandmarkMap& local, RobotId self, std::uint32_t self_incarnation,
                   std::span<const MapSource> sources, const GlobalMap& associated, JoiningStats* stats,
                   const JoiningOptions& options) {
  JoiningStats st;
  GlobalMap out = associated;
  const int k_count = static_cast<int>(associated.map.size());
  const int s_count = static_cast<int>(sources.size());
  // Source landmarks by origin.
  std::map<std::tuple<RobotId, std::uint32_t, std::uint32_t>, const Landmark*> by_origin;
  std::map<std::pair<RobotId, std::uint32_t>, int> source_index;
  for (const Landmark& l : local.landmarks) by_origin[{self, self_incarnation, l.id}] = &l;
  for (int s = 0; s < s_count; ++s) {
    source_index[{sources[s].robot, sources[s].incarnation}] = s;
    for (const Landmark& l : sources[s].map.landmarks) by_origin[{sources[s].robot, sources[s].incarnation, l.id}] = &l;
  }
  std::vector<Observed> obs;
  for (int k = 0; k < k_count; ++k) {
    for (const LandmarkOrigin& o : associated.origins[k]) {
      const auto it = by_origin.find({o.robot, o.incarnation, o.id});
      if (it == by_origin.end()) continue;
      int s = -1;
      if (!(o.robot == self && o.incarnation == self_incarnation)) {
        const auto si = source_index.find({o.robot, o.incarnation});
        if (si == source_index.end()) continue;
        s = si->second;
      }
      Eigen::Matrix2d w;
      if (!it->second->mean.allFinite() || !Information(it->second->cov, &w)) continue;
      obs.push_back({k, s, it->second->mean, w, Eigen::LLT<Eigen::Matrix2d>(w).matrixU()});
    }
  }
  const int n = 2 * k_count + 3 * s_count;
  st.unknowns = n;
  st.measurements = static_cast<int>(obs.size());
  if (k_count == 0) {
    if (stats) *stats = st;
    return out;
  }
  std::vector<Eigen::Vector2d> g(k_count);
  for (int k = 0; k < k_count; ++k) g[k] = associated.map.landmarks[k].mean;
  std::vector<Pose2> t(s_count);
  std::vector<Eigen::Matrix3d> prior(s_count);
  for (int s = 0; s < s_count; ++s) {
    t[s] = sources[s].to_own;
    Eigen::Matrix3d c = sources[s].to_own_cov * 1e4;
    if (!c.allFinite() || Eigen::FullPivLU<Eigen::Matrix3d>(c).rank() < 3) c = Eigen::Matrix3d::Identity() * 1e4;
    prior[s] = c.inverse();
  }
  const std::vector<Pose2> t0 = t;
  std::vector<Eigen::Matrix3d> prior_sqrt(s_count);  // S with S^T S = the prior's information
  for (int s = 0; s < s_count; ++s) prior_sqrt[s] = Eigen::LLT<Eigen::Matrix3d>(prior[s]).matrixU();

  // The shared least-squares kernel: landmarks (2 each), then the sources' transforms (3 each).
  std::vector<int> sizes(static_cast<std::size_t>(k_count), 2);
  sizes.insert(sizes.end(), static_cast<std::size_t>(s_count), 3);
  BlockNormalEquations eq(std::move(sizes));
  std::vector<int> handle(obs.size());
  for (std::size_t i = 0; i < obs.size(); ++i) {
    handle[i] = obs[i].source < 0 ? eq.Couple({obs[i].landmark})
                                  : eq.Couple({obs[i].landmark, k_count + obs[i].source});
  }
  std::vector<int> prior_handle(s_count), tiny_handle(k_count);
  for (int s = 0; s < s_count; ++s) prior_handle[s] = eq.Couple({k_count + s});
  for (int k = 0; k < k_count; ++k) tiny_handle[k] = eq.Couple({k});
  eq.Finalize();
  const Eigen::Matrix2d tiny = Eigen::Matrix2d::Identity() * std::sqrt(1e-9);

  Eigen::VectorXd dx;
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    eq.SetZero();
    for (std::size_t i = 0; i < obs.size(); ++i) {
      const Observed& o = obs[i];
      if (o.source < 0) {
        eq.Add(handle[i], o.sqrt_w, o.sqrt_w * (g[o.landmark] - o.z), o.weight);
        continue;
      }
      Eigen::Matrix<double, 2, 3> j_t;
      Eigen::Matrix2d j_g;
      const Eigen::Vector2d pred = t[o.source].TransformTo(g[o.landmark], &j_t, &j_g);
      Eigen::Matrix<double, 2, 5> j;
      j << o.sqrt_w * j_g, o.sqrt_w * j_t;
      eq.Add(handle[i], j, o.sqrt_w * (pred - o.z), o.weight);
    }
    for (int s = 0; s < s_count; ++s) {
      const Eigen::Vector3d e(t[s].x - t0[s].x, t[s].y - t0[s].y, WrapAngle(t[s].theta - t0[s].theta));
      eq.Add(prior_handle[s], prior_sqrt[s], prior_sqrt[s] * e);
    }
    // A landmark nothing measured (all its inputs invalid) keeps its place: a tiny damping.
    for (int k = 0; k < k_count; ++k) eq.Add(tiny_handle[k], tiny, Eigen::Vector2d::Zero());
    if (!eq.Solve(0.0, &dx) || !dx.allFinite()) {
      if (stats) *stats = st;
      return associated;
    }
    for (int k = 0; k < k_count; ++k) g[k] += dx.segment<2>(eq.offset(k));
    for (int s = 0; s < s_count; ++s) {
      t[s] = t[s].Retract(dx.segment<3>(eq.offset(k_count + s)));
    }
    st.iterations = iter + 1;
    // Reweighted for the first `reweightings` steps: each measurement's Huber weight from its
    // Mahalanobis residual at the new estimate. The weights are then held, and Gauss-Newton
    // converges on the weighted problem (plain reweighting to the end converges only linearly,
    // slowly where a landmark has just two copies).
    const bool reweighting = options.huber > 0.0 && iter < options.reweightings;
    if (reweighting) {
      st.downweighted = 0;
      const RobustKernel huber{RobustLoss::kHuber, options.huber};
      for (Observed& o : obs) {
        const Eigen::Vector2d pred = o.source < 0 ? g[o.landmark] : t[o.source].TransformTo(g[o.landmark]);
        const Eigen::Vector2d e = o.z - pred;
        o.weight = huber.Weight(e.dot(o.w * e));
        st.downweighted += o.weight < 1.0 ? 1 : 0;
      }
    }
    if (!reweighting && dx.lpNorm<Eigen::Infinity>() < 1e-7) {
      st.converged = true;
      break;
    }
  }
  // Marginal covariances of the landmarks, from the normal equations of the last linearisation
  // (at most one step from the optimum).
  std::vector<int> landmarks(static_cast<std::size_t>(k_count));
  for (int k = 0; k < k_count; ++k) landmarks[k] = k;
  const std::vector<Eigen::MatrixXd> marginals = eq.Marginals(landmarks);
  if (marginals.size() != landmarks.size()) {
    if (stats) *stats = st;
    return associated;
  }
  st.solved = true;
  for (int k = 0; k < k_count; ++k) {
    Landmark& l = out.map.landmarks[k];
    l.mean = g[k];
    const Eigen::Matrix2d c = marginals[k];
    l.cov = 0.5 * (c + c.transpose());
  }
  if (stats) *stats = st;
  return out;
}

}  // namespace mapmesh
