// The reference's solver chosen by measurement (issue 34): the central solve of
// BM_CentralBatch (batch_bench.cc), the same factors from the same start, by Ceres (sparse normal
// Cholesky, Levenberg-Marquardt), then ceres::Covariance for every landmark's marginal, as the
// reference delivers them. Built only when Ceres is installed (libceres-dev).

#include <benchmark/benchmark.h>
#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <array>
#include <map>
#include <vector>

#include "bench/batch_problem.h"

namespace mapmesh {
namespace {

using RowMajor23 = Eigen::Matrix<double, 2, 3, Eigen::RowMajor>;
using RowMajor33 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;
using RowMajor22 = Eigen::Matrix<double, 2, 2, Eigen::RowMajor>;

// The odometry factor: S (Between(a, b) - delta), the heading wrapped.
class OdometryCost : public ceres::SizedCostFunction<3, 3, 3> {
 public:
  OdometryCost(const Pose2& delta, const Eigen::Matrix3d& cov) : delta_(delta) {
    white_ = Eigen::Matrix3d(cov + 1e-10 * Eigen::Matrix3d::Identity())
                 .llt()
                 .matrixL()
                 .solve(Eigen::Matrix3d::Identity());
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    Eigen::Matrix3d ja, jb;
    const Eigen::Vector3d e = RelativePoseError({p[0][0], p[0][1], p[0][2]}, {p[1][0], p[1][1], p[1][2]}, delta_, &ja,
                                                &jb);
    Eigen::Map<Eigen::Vector3d> res(residuals);
    res = white_ * e;
    if (jacobians && jacobians[0]) Eigen::Map<RowMajor33>{jacobians[0]} = white_ * ja;
    if (jacobians && jacobians[1]) Eigen::Map<RowMajor33>{jacobians[1]} = white_ * jb;
    return true;
  }

 private:
  Pose2 delta_;
  Eigen::Matrix3d white_;
};

// The range-bearing factor: S (h(pose, m) - z), the bearing wrapped.
class RangeBearingCost : public ceres::SizedCostFunction<2, 3, 2> {
 public:
  RangeBearingCost(const Eigen::Vector2d& z, const Eigen::Matrix2d& cov) : z_(z) {
    white_ = cov.llt().matrixL().solve(Eigen::Matrix2d::Identity());
  }
  bool Evaluate(double const* const* p, double* residuals, double** jacobians) const override {
    Eigen::Matrix<double, 2, 3> jp;
    Eigen::Matrix2d jm;
    const Eigen::Vector2d e = RangeBearingError({p[0][0], p[0][1], p[0][2]}, {p[1][0], p[1][1]}, z_, &jp, &jm);
    Eigen::Map<Eigen::Vector2d> res(residuals);
    res = white_ * e;
    if (jacobians && jacobians[0]) Eigen::Map<RowMajor23>{jacobians[0]} = white_ * jp;
    if (jacobians && jacobians[1]) Eigen::Map<RowMajor22>{jacobians[1]} = white_ * jm;
    return true;
  }

 private:
  Eigen::Vector2d z_;
  Eigen::Matrix2d white_;
};

// Every robot's nodes (from its own optimum: the starts are true, so no placement) and every
// landmark (the mean of the robots' own estimates), as SolveCentralBatch starts.
struct Estimate {
  std::vector<std::vector<std::array<double, 3>>> poses;
  std::map<std::int32_t, std::array<double, 2>> landmarks;
};

Estimate Start(const bench::BatchProblemData& d) {
  Estimate est;
  std::map<std::int32_t, std::pair<Eigen::Vector2d, int>> sum;
  for (std::size_t r = 0; r < d.input.logs.size(); ++r) {
    est.poses.emplace_back();
    for (const BatchPose& p : d.singles[r].trajectories.at(d.input.logs[r].robot)) {
      est.poses.back().push_back({p.pose.x, p.pose.y, p.pose.theta});
    }
    for (const Landmark& l : d.singles[r].map.landmarks) {
      auto& [s, k] = sum.try_emplace(l.signature, Eigen::Vector2d::Zero(), 0).first->second;
      s += l.mean;
      ++k;
    }
  }
  for (const auto& [sig, s] : sum) est.landmarks[sig] = {s.first.x() / s.second, s.first.y() / s.second};
  return est;
}

void BM_CentralBatchCeres(benchmark::State& state) {
  const bench::BatchProblemData& d = bench::Park4x8();
  const Estimate start = Start(d);
  Estimate est;
  int iterations = 0;
  std::map<std::int32_t, Eigen::Matrix2d> cov;
  for (auto _ : state) {
    state.PauseTiming();
    est = start;
    state.ResumeTiming();
    ceres::Problem problem;
    for (std::size_t r = 0; r < d.input.logs.size(); ++r) {
      const BatchRobotLog& log = d.input.logs[r];
      for (std::size_t i = 0; i < log.nodes.size(); ++i) {
        if (i > 0) {
          problem.AddResidualBlock(new OdometryCost(log.nodes[i].delta, log.nodes[i].delta_cov), nullptr,
                                   est.poses[r][i - 1].data(), est.poses[r][i].data());
        }
        for (const BatchObservation& o : log.nodes[i].obs) {
          problem.AddResidualBlock(new RangeBearingCost(o.z, log.obs_cov), nullptr, est.poses[r][i].data(),
                                   est.landmarks.at(o.landmark).data());
        }
      }
      problem.SetParameterBlockConstant(est.poses[r][0].data());  // the true start
    }
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.function_tolerance = 1e-10;
    options.parameter_tolerance = 1e-9;
    options.max_num_iterations = 100;
    options.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    iterations = static_cast<int>(summary.iterations.size());
    ceres::Covariance::Options copt;
    copt.num_threads = 1;
    ceres::Covariance covariance(copt);
    std::vector<std::pair<const double*, const double*>> pairs;
    for (const auto& [sig, p] : est.landmarks) pairs.emplace_back(p.data(), p.data());
    if (!covariance.Compute(pairs, &problem)) state.SkipWithError("ceres::Covariance failed");
    RowMajor22 b;
    for (const auto& [sig, p] : est.landmarks) {
      covariance.GetCovarianceBlock(p.data(), p.data(), b.data());
      cov[sig] = b;
    }
  }
  // The same optimum as the project's solver: the largest landmark and covariance differences.
  const BatchSolution own = SolveCentralBatch(d.input.logs, d.singles, {}, {{}, StartKnowledge::kKnown});
  double worst = 0.0, worst_cov = 0.0;
  for (const Landmark& l : own.map.landmarks) {
    const auto& p = est.landmarks.at(l.signature);
    worst = std::max(worst, (l.mean - Eigen::Vector2d(p[0], p[1])).norm());
    worst_cov = std::max(worst_cov, (l.cov - cov.at(l.signature)).cwiseAbs().maxCoeff());
  }
  state.counters["iterations"] = iterations;
  state.counters["max_diff_to_own_m"] = worst;
  state.counters["max_cov_diff"] = worst_cov;
}
BENCHMARK(BM_CentralBatchCeres)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mapmesh
