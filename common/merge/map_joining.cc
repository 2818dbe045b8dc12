#include "common/merge/map_joining.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/Sparse>
#include <cmath>
#include <map>
#include <tuple>
#include <vector>

namespace mapmesh {
namespace {

struct Observed {
  int landmark;  // global index
  int source;    // -1: the own map
  Eigen::Vector2d z;
  Eigen::Matrix2d w;    // information
  double weight = 1.0;  // the robust kernel's weight at the last estimate
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
      obs.push_back({k, s, it->second->mean, w});
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

  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver;
  Eigen::SparseMatrix<double> h(n, n);
  for (int iter = 0; iter < options.max_iterations; ++iter) {
    std::vector<Eigen::Triplet<double>> trip;
    Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
    auto add_block = [&](int r0, int c0, const Eigen::MatrixXd& m) {
      for (int i = 0; i < m.rows(); ++i)
        for (int j = 0; j < m.cols(); ++j)
          if (m(i, j) != 0.0) trip.emplace_back(r0 + i, c0 + j, m(i, j));
    };
    for (const Observed& o : obs) {
      const int gi = 2 * o.landmark;
      const Eigen::Matrix2d w = o.w * o.weight;
      if (o.source < 0) {
        add_block(gi, gi, w);
        b.segment<2>(gi) += w * (o.z - g[o.landmark]);
        continue;
      }
      const Pose2& ts = t[o.source];
      const double c = std::cos(ts.theta), s = std::sin(ts.theta);
      Eigen::Matrix2d rt;
      rt << c, s, -s, c;
      const Eigen::Vector2d d = g[o.landmark] - Eigen::Vector2d(ts.x, ts.y);
      const Eigen::Vector2d pred = rt * d;
      Eigen::Matrix<double, 2, 5> j;  // d pred / d (g, t_x, t_y, theta)
      j.leftCols<2>() = rt;
      j.block<2, 2>(0, 2) = -rt;
      Eigen::Matrix2d drt;
      drt << -s, c, -c, -s;
      j.col(4) = drt * d;
      const Eigen::Matrix<double, 5, 5> jtj = j.transpose() * w * j;
      const Eigen::Matrix<double, 5, 1> jtr = j.transpose() * w * (o.z - pred);
      const int ti = 2 * k_count + 3 * o.source;
      add_block(gi, gi, jtj.topLeftCorner<2, 2>());
      add_block(gi, ti, jtj.topRightCorner<2, 3>());
      add_block(ti, gi, jtj.bottomLeftCorner<3, 2>());
      add_block(ti, ti, jtj.bottomRightCorner<3, 3>());
      b.segment<2>(gi) += jtr.head<2>();
      b.segment<3>(ti) += jtr.tail<3>();
    }
    for (int s = 0; s < s_count; ++s) {
      const int ti = 2 * k_count + 3 * s;
      add_block(ti, ti, prior[s]);
      const Eigen::Vector3d e(t0[s].x - t[s].x, t0[s].y - t[s].y, WrapAngle(t0[s].theta - t[s].theta));
      b.segment<3>(ti) += prior[s] * e;
    }
    // A landmark nothing measured (all its inputs invalid) keeps its place: a tiny prior.
    for (int k = 0; k < k_count; ++k) add_block(2 * k, 2 * k, Eigen::Matrix2d::Identity() * 1e-9);
    h.setFromTriplets(trip.begin(), trip.end());
    solver.compute(h);
    if (solver.info() != Eigen::Success) {
      if (stats) *stats = st;
      return associated;
    }
    const Eigen::VectorXd dx = solver.solve(b);
    if (!dx.allFinite()) {
      if (stats) *stats = st;
      return associated;
    }
    for (int k = 0; k < k_count; ++k) g[k] += dx.segment<2>(2 * k);
    for (int s = 0; s < s_count; ++s) {
      const Eigen::Vector3d d = dx.segment<3>(2 * k_count + 3 * s);
      t[s] = {t[s].x + d(0), t[s].y + d(1), WrapAngle(t[s].theta + d(2))};
    }
    st.iterations = iter + 1;
    // Reweighted for the first `reweightings` steps: each measurement's Huber weight from its
    // Mahalanobis residual at the new estimate. The weights are then held, and Gauss-Newton
    // converges on the weighted problem (plain reweighting to the end converges only linearly,
    // slowly where a landmark has just two copies).
    const bool reweighting = options.huber > 0.0 && iter < options.reweightings;
    if (reweighting) {
      st.downweighted = 0;
      for (Observed& o : obs) {
        const Eigen::Vector2d pred = o.source < 0 ? g[o.landmark] : t[o.source].Inverse().Apply(g[o.landmark]);
        const Eigen::Vector2d e = o.z - pred;
        const double r = std::sqrt(e.dot(o.w * e));
        o.weight = r > options.huber ? options.huber / r : 1.0;
        st.downweighted += o.weight < 1.0 ? 1 : 0;
      }
    }
    if (!reweighting && dx.lpNorm<Eigen::Infinity>() < 1e-7) {
      st.converged = true;
      break;
    }
  }
  // Marginal covariances: two columns of the inverse per landmark (the factor from the last
  // linearisation, at most one step from the optimum).
  st.solved = true;
  Eigen::MatrixXd e = Eigen::MatrixXd::Zero(n, 2);
  for (int k = 0; k < k_count; ++k) {
    e.setZero();
    e(2 * k, 0) = 1.0;
    e(2 * k + 1, 1) = 1.0;
    const Eigen::MatrixXd col = solver.solve(e);
    Landmark& l = out.map.landmarks[k];
    l.mean = g[k];
    const Eigen::Matrix2d c = col.block<2, 2>(2 * k, 0);
    l.cov = 0.5 * (c + c.transpose());
  }
  if (stats) *stats = st;
  return out;
}

}  // namespace mapmesh
