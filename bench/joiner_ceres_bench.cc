// The submap joiner's solver chosen by measurement (issue 19): the same full re-solve of the
// 50th of 50 submaps x 30 landmarks as BM_JoinSubmapFullResolve (joiner_bench.cc), here by
// Ceres (sparse normal Cholesky, Levenberg-Marquardt, then ceres::Covariance for the landmarks'
// joint covariance, as the joiner delivers it), each warm-started from its own optimum over the
// first 49 submaps. Built only when Ceres is installed (libceres-dev).

#include <benchmark/benchmark.h>
#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <array>
#include <map>
#include <memory>

#include "bench/joiner_problem.h"
#include "common/geometry/pose2.h"
#include "common/slam/submap_joiner.h"

namespace mapmesh {
namespace {

// One submap's residual, whitened by its covariance: L^-1 (h(X_k, X_k+1, L...) - x_k), with the
// heading difference wrapped. Parameter blocks: X_k, X_k+1 (3 each), then each landmark (2).
class SubmapResidual : public ceres::CostFunction {
 public:
  explicit SubmapResidual(const SubmapEstimate& s)
      : x_(s.x), whiten_(s.p.llt().matrixL().solve(Eigen::MatrixXd::Identity(s.x.size(), s.x.size()))) {
    set_num_residuals(static_cast<int>(s.x.size()));
    mutable_parameter_block_sizes()->assign({3, 3});
    for (std::size_t j = 0; j < s.keys.size(); ++j) mutable_parameter_block_sizes()->push_back(2);
  }

  bool Evaluate(double const* const* params, double* residuals, double** jacobians) const override {
    const Pose2 origin{params[0][0], params[0][1], params[0][2]};
    const Pose2 end{params[1][0], params[1][1], params[1][2]};
    std::vector<Eigen::Vector2d> landmarks;
    const std::size_t m = parameter_block_sizes().size() - 2;
    for (std::size_t j = 0; j < m; ++j) landmarks.emplace_back(params[2 + j][0], params[2 + j][1]);
    Eigen::MatrixXd jac;
    Eigen::VectorXd e = PredictSubmap(origin, end, landmarks, jacobians ? &jac : nullptr) - x_;
    e(2) = WrapAngle(e(2));
    Eigen::Map<Eigen::VectorXd>(residuals, num_residuals()) = whiten_ * e;
    if (!jacobians) return true;
    const Eigen::MatrixXd wj = whiten_ * jac;
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    for (std::size_t b = 0; b < m + 2; ++b) {
      if (!jacobians[b]) continue;
      const int cols = b < 2 ? 3 : 2;
      const Eigen::Index col = b < 2 ? 3 * static_cast<Eigen::Index>(b) : 6 + 2 * static_cast<Eigen::Index>(b - 2);
      Eigen::Map<RowMajor>(jacobians[b], num_residuals(), cols) = wj.middleCols(col, cols);
    }
    return true;
  }

 private:
  Eigen::VectorXd x_;
  Eigen::MatrixXd whiten_;
};

// The joint estimate: frames X_1..X_K (X_0 fixed at the origin) and every landmark.
struct Estimate {
  std::vector<std::array<double, 3>> frames;
  std::map<std::uint32_t, std::array<double, 2>> landmarks;
};

// Adds submap k's unknowns where they are new, placed by composing it onto its start frame.
void Extend(Estimate& est, const SubmapEstimate& s) {
  const auto& f = est.frames.back();
  const Pose2 start{f[0], f[1], f[2]};
  const Pose2 end = start * Pose2{s.x(0), s.x(1), s.x(2)};
  for (std::size_t j = 0; j < s.keys.size(); ++j) {
    if (est.landmarks.count(s.keys[j])) continue;
    const Eigen::Vector2d p = start.Apply(s.x.segment<2>(3 + 2 * static_cast<Eigen::Index>(j)));
    est.landmarks[s.keys[j]] = {p.x(), p.y()};
  }
  est.frames.push_back({end.x, end.y, end.theta});
}

// Solves the first `count` submaps from est; with `cov`, also the landmarks' joint covariance
// (2n x 2n, what the joiner hands the agent), by ceres::Covariance.
ceres::Solver::Summary Solve(const std::vector<SubmapEstimate>& submaps, std::size_t count, Estimate& est,
                             Eigen::MatrixXd* cov = nullptr) {
  ceres::Problem problem;
  for (std::size_t k = 0; k < count; ++k) {
    std::vector<double*> blocks = {est.frames[k].data(), est.frames[k + 1].data()};
    for (std::uint32_t key : submaps[k].keys) blocks.push_back(est.landmarks.at(key).data());
    problem.AddResidualBlock(new SubmapResidual(submaps[k]), nullptr, blocks);
  }
  problem.SetParameterBlockConstant(est.frames[0].data());
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  options.function_tolerance = 1e-8;
  options.parameter_tolerance = 1e-8;
  options.max_num_iterations = 20;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (cov) {
    std::vector<const double*> blocks;
    for (const auto& [key, p] : est.landmarks) blocks.push_back(p.data());
    ceres::Covariance::Options copt;
    copt.num_threads = 1;
    ceres::Covariance covariance(copt);
    std::vector<std::pair<const double*, const double*>> pairs;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      for (std::size_t j = i; j < blocks.size(); ++j) pairs.emplace_back(blocks[i], blocks[j]);
    }
    if (!covariance.Compute(pairs, &problem)) return summary;
    const Eigen::Index n = static_cast<Eigen::Index>(blocks.size());
    cov->setZero(2 * n, 2 * n);
    Eigen::Matrix<double, 2, 2, Eigen::RowMajor> b;
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index j = i; j < n; ++j) {
        covariance.GetCovarianceBlock(blocks[i], blocks[j], b.data());
        cov->block<2, 2>(2 * i, 2 * j) = b;
        cov->block<2, 2>(2 * j, 2 * i) = b.transpose();
      }
    }
  }
  return summary;
}

void BM_JoinSubmapFullResolveCeres(benchmark::State& state) {
  const std::vector<SubmapEstimate> submaps = bench::MakeJoinerSubmaps();
  const std::size_t k = submaps.size();
  Estimate base;
  base.frames.push_back({0.0, 0.0, 0.0});
  for (std::size_t i = 0; i + 1 < k; ++i) Extend(base, submaps[i]);
  Solve(submaps, k - 1, base);
  Extend(base, submaps.back());
  int iterations = 0;
  Estimate est;
  Eigen::MatrixXd cov;
  for (auto _ : state) {
    state.PauseTiming();
    est = base;
    state.ResumeTiming();
    iterations = static_cast<int>(Solve(submaps, k, est, &cov).iterations.size());
    benchmark::DoNotOptimize(cov.data());
  }
  // The same optimum as the Eigen joiner's full re-solve: the largest landmark difference.
  SubmapJoiner eigen({.window = 1000});
  for (const SubmapEstimate& s : submaps) eigen.Add(s);
  double worst = 0.0;
  const JoinedMap& joined = eigen.last();
  for (std::size_t i = 0; i < joined.keys.size(); ++i) {
    const auto& p = est.landmarks.at(joined.keys[i]);
    worst = std::max(worst, (joined.means[i] - Eigen::Vector2d(p[0], p[1])).norm());
  }
  // The keys are increasing in both, so the covariances line up.
  state.counters["max_cov_diff"] = (cov - joined.cov).cwiseAbs().maxCoeff();
  state.counters["iterations"] = iterations;
  state.counters["max_diff_to_eigen_m"] = worst;
  state.counters["landmarks"] = static_cast<double>(est.landmarks.size());
}
BENCHMARK(BM_JoinSubmapFullResolveCeres)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mapmesh
