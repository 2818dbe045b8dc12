#include "common/solver/least_squares.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <tuple>

#include <Eigen/Dense>
#include <random>

namespace mapmesh {
namespace {

// rho'(s) is what Weight returns, and each loss is the square near zero.
TEST(RobustKernel, WeightIsTheDerivativeOfRho) {
  for (RobustLoss loss : {RobustLoss::kNone, RobustLoss::kHuber, RobustLoss::kCauchy}) {
    const RobustKernel k{loss, 1.5};
    for (double s : {1e-4, 0.3, 1.0, 2.0, 2.26, 5.0, 40.0, 1e4}) {
      const double h = 1e-6 * std::max(1.0, s);
      const double numeric = (k.Rho(s + h) - k.Rho(s - h)) / (2 * h);
      EXPECT_NEAR(k.Weight(s), numeric, 1e-6) << static_cast<int>(loss) << " s " << s;
    }
    EXPECT_NEAR(k.Rho(1e-6), 1e-6, 1e-12);
    EXPECT_LE(k.Rho(100.0), 100.0);
  }
  // Huber is the square up to c^2, then grows linearly in |r|; Cauchy grows with log.
  const RobustKernel huber{RobustLoss::kHuber, 2.0}, cauchy{RobustLoss::kCauchy, 2.0};
  EXPECT_DOUBLE_EQ(huber.Rho(3.9), 3.9);
  EXPECT_NEAR(huber.Rho(400.0), 2 * 2 * 20 - 4, 1e-12);
  EXPECT_NEAR(cauchy.Rho(400.0), 4 * std::log(101.0), 1e-12);
}

// A random sparse linear problem: variables of sizes 1-3, factors coupling 1-3 of them, each
// variable also given a prior so that H is positive definite.
struct LinearProblem {
  std::vector<int> sizes;
  struct Factor {
    std::vector<int> vars;
    Eigen::MatrixXd j;
    Eigen::VectorXd r;
    double w;
  };
  std::vector<Factor> factors;
};

LinearProblem RandomLinearProblem(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> size(1, 3), count(1, 3);
  std::normal_distribution<double> n;
  LinearProblem p;
  const int nv = 8 + static_cast<int>(seed % 20);
  for (int v = 0; v < nv; ++v) p.sizes.push_back(size(rng));
  std::uniform_int_distribution<int> pick(0, nv - 1);
  auto add = [&](std::vector<int> vars) {
    int cols = 0;
    for (int v : vars) cols += p.sizes[static_cast<std::size_t>(v)];
    const int rows = 1 + static_cast<int>(rng() % 4);
    LinearProblem::Factor f{vars, Eigen::MatrixXd(rows, cols), Eigen::VectorXd(rows), 0.5 + (rng() % 3) * 0.25};
    for (int i = 0; i < f.j.size(); ++i) f.j.data()[i] = n(rng);
    for (int i = 0; i < rows; ++i) f.r(i) = n(rng);
    p.factors.push_back(f);
  };
  for (int v = 0; v < nv; ++v) {
    // A prior: identity rows over the variable.
    const int s = p.sizes[static_cast<std::size_t>(v)];
    LinearProblem::Factor f{{v}, Eigen::MatrixXd::Identity(s, s), Eigen::VectorXd::Zero(s), 1.0};
    for (int i = 0; i < s; ++i) f.r(i) = n(rng);
    p.factors.push_back(f);
  }
  for (int k = 0; k < 3 * nv; ++k) {
    std::vector<int> vars;
    const int c = count(rng);
    while (static_cast<int>(vars.size()) < c) {
      const int v = pick(rng);
      if (std::find(vars.begin(), vars.end(), v) == vars.end()) vars.push_back(v);
    }
    add(vars);
  }
  return p;
}

// The dense H = sum w J^T J and g = sum w J^T r of the problem, in eq's layout of the variables.
void DenseSystem(const LinearProblem& p, const BlockNormalEquations& eq, Eigen::MatrixXd* h, Eigen::VectorXd* g) {
  const int n = eq.dim();
  *h = Eigen::MatrixXd::Zero(n, n);
  *g = Eigen::VectorXd::Zero(n);
  for (const auto& f : p.factors) {
    // The factor's Jacobian spread over the whole state.
    Eigen::MatrixXd full = Eigen::MatrixXd::Zero(f.j.rows(), n);
    int col = 0;
    for (int v : f.vars) {
      full.middleCols(eq.offset(v), eq.size(v)) = f.j.middleCols(col, eq.size(v));
      col += eq.size(v);
    }
    *h += f.w * full.transpose() * full;
    *g += f.w * full.transpose() * f.r;
  }
}

// A seed, and the factorisation forced (or chosen: kAuto).
class LinearSystemTest : public ::testing::TestWithParam<std::tuple<std::uint64_t, Factorisation>> {
 protected:
  std::uint64_t seed() const { return std::get<0>(GetParam()); }
  Factorisation factorisation() const { return std::get<1>(GetParam()); }
};

// The block accumulation, the damped solve and the marginals equal a dense computation of
// H = sum w J^T J, g = sum w J^T r, whatever the variables' order within a factor, and whether
// the factorisation is sparse or dense.
TEST_P(LinearSystemTest, SolveAndMarginalsMatchTheDenseSystem) {
  const LinearProblem p = RandomLinearProblem(seed());
  BlockNormalEquations eq(p.sizes, factorisation());
  std::vector<int> handles;
  for (const auto& f : p.factors) handles.push_back(eq.Couple(f.vars));
  eq.Finalize();
  for (std::size_t k = 0; k < p.factors.size(); ++k) {
    const auto& f = p.factors[k];
    eq.Add(handles[k], f.j, f.r, f.w);
  }
  Eigen::MatrixXd h;
  Eigen::VectorXd g;
  DenseSystem(p, eq, &h, &g);
  EXPECT_LT((eq.gradient() - g).cwiseAbs().maxCoeff(), 1e-12);
  for (double lambda : {0.0, 0.1, 3.0}) {
    Eigen::VectorXd dx;
    ASSERT_TRUE(eq.Solve(lambda, &dx));
    Eigen::MatrixXd damped = h;
    damped.diagonal() += lambda * h.diagonal();
    const Eigen::VectorXd expected = damped.ldlt().solve(-g);
    EXPECT_LT((dx - expected).cwiseAbs().maxCoeff(), 1e-9) << "lambda " << lambda;
  }
  std::vector<int> all(p.sizes.size());
  for (std::size_t v = 0; v < all.size(); ++v) all[v] = static_cast<int>(v);
  const std::vector<Eigen::MatrixXd> marg = eq.Marginals(all);
  ASSERT_EQ(marg.size(), all.size());
  const Eigen::MatrixXd inv = h.inverse();
  for (int v : all) {
    EXPECT_LT((marg[static_cast<std::size_t>(v)] - inv.block(eq.offset(v), eq.offset(v), eq.size(v), eq.size(v)))
                  .cwiseAbs()
                  .maxCoeff(),
              1e-9)
        << "variable " << v;
  }
  // The joint covariance of some variables, in a shuffled order, cross blocks included.
  std::vector<int> some;
  for (int v : all) {
    if (v % 3 != 1) some.push_back(v);
  }
  std::reverse(some.begin(), some.end());
  const Eigen::MatrixXd joint = eq.JointMarginal(some);
  int row = 0;
  for (int a : some) {
    int col = 0;
    for (int b : some) {
      EXPECT_LT((joint.block(row, col, eq.size(a), eq.size(b)) -
                 inv.block(eq.offset(a), eq.offset(b), eq.size(a), eq.size(b)))
                    .cwiseAbs()
                    .maxCoeff(),
                1e-9)
          << "variables " << a << ", " << b;
      col += eq.size(b);
    }
    row += eq.size(a);
  }
  EXPECT_EQ(joint.rows(), row);
  EXPECT_EQ(eq.JointMarginal({}).size(), 0);
  // Cleared, the system holds nothing but its pattern.
  eq.SetZero();
  EXPECT_EQ(eq.gradient().norm(), 0.0);
}

// A factor in information form (a dense prior from marginalisation) adds exactly what the same
// factor as a Jacobian and residual adds: h = w J^T J and g = w J^T r, in the coupling's order.
TEST_P(LinearSystemTest, InformationFormEqualsTheFactorItCameFrom) {
  const LinearProblem p = RandomLinearProblem(seed());
  BlockNormalEquations by_factor(p.sizes, factorisation()), by_information(p.sizes, factorisation());
  std::vector<int> handles;
  for (const auto& f : p.factors) {
    handles.push_back(by_factor.Couple(f.vars));
    by_information.Couple(f.vars);
  }
  by_factor.Finalize();
  by_information.Finalize();
  for (std::size_t k = 0; k < p.factors.size(); ++k) {
    const auto& f = p.factors[k];
    by_factor.Add(handles[k], f.j, f.r, f.w);
    by_information.AddInformation(handles[k], f.w * f.j.transpose() * f.j, f.w * f.j.transpose() * f.r);
  }
  EXPECT_LT((by_factor.gradient() - by_information.gradient()).cwiseAbs().maxCoeff(), 1e-12);
  Eigen::VectorXd a, b;
  ASSERT_TRUE(by_factor.Solve(0.0, &a));
  ASSERT_TRUE(by_information.Solve(0.0, &b));
  EXPECT_LT((a - b).cwiseAbs().maxCoeff(), 1e-9);
}

// The symbolic count of the factor's entries is the Cholesky factor's block structure: a dense
// factorisation of H in the layout, whose random values leave no accidental zero block, has
// non-zeros in exactly the blocks it counts (each block whole, a diagonal one its lower
// triangle). kAuto factorises densely exactly when that count reaches kDenseFillShare of the
// triangle.
TEST_P(LinearSystemTest, SymbolicFactorEntriesAreTheFactorsNonZeros) {
  const LinearProblem p = RandomLinearProblem(seed());
  BlockNormalEquations eq(p.sizes, factorisation());
  for (const auto& f : p.factors) eq.Couple(f.vars);
  eq.Finalize();
  const int n = eq.dim();
  Eigen::MatrixXd h;
  Eigen::VectorXd g;
  DenseSystem(p, eq, &h, &g);
  const Eigen::MatrixXd l = h.llt().matrixL();
  Eigen::Index nonzeros = 0;
  for (int a = 0; a < eq.variables(); ++a) {
    for (int b = 0; b < eq.variables(); ++b) {
      if (eq.offset(b) > eq.offset(a)) continue;  // the blocks on and below the diagonal
      const int sa = eq.size(a), sb = eq.size(b);
      if (a == b) {
        nonzeros += sa * (sa + 1) / 2;
      } else if (l.block(eq.offset(a), eq.offset(b), sa, sb).cwiseAbs().maxCoeff() > 1e-13) {
        nonzeros += sa * sb;
      }
    }
  }
  EXPECT_EQ(eq.factor_entries(), nonzeros);
  const bool dense_enough = static_cast<double>(nonzeros) >= kDenseFillShare * 0.5 * n * (n + 1);
  switch (factorisation()) {
    case Factorisation::kAuto: EXPECT_EQ(eq.dense(), dense_enough); break;
    case Factorisation::kSparse: EXPECT_FALSE(eq.dense()); break;
    case Factorisation::kDense: EXPECT_TRUE(eq.dense()); break;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Seeds, LinearSystemTest,
    ::testing::Combine(::testing::Range<std::uint64_t>(1, 21),
                       ::testing::Values(Factorisation::kAuto, Factorisation::kSparse, Factorisation::kDense)));

// kAuto: a chain of variables (each coupled to the next: no fill) is factorised sparsely, one
// factor over every variable densely.
TEST(BlockNormalEquations, AutoFactorisesAChainSparselyAndACliqueDensely) {
  const std::vector<int> sizes(40, 2);
  BlockNormalEquations chain(sizes), clique(sizes);
  for (int v = 0; v + 1 < 40; ++v) chain.Couple({v, v + 1});
  std::vector<int> all(40);
  for (int v = 0; v < 40; ++v) all[static_cast<std::size_t>(v)] = v;
  clique.Couple(all);
  chain.Finalize();
  clique.Finalize();
  EXPECT_FALSE(chain.dense());
  EXPECT_TRUE(clique.dense());
  EXPECT_EQ(clique.factor_entries(), 80 * 81 / 2);
}

TEST(BlockNormalEquations, ASingularSystemIsReportedNotSolved) {
  BlockNormalEquations eq({2, 2});
  const int h = eq.Couple({0, 1});
  eq.Finalize();
  // One row over four unknowns: rank one.
  Eigen::MatrixXd j(1, 4);
  j << 1, 2, 3, 4;
  eq.Add(h, j, Eigen::VectorXd::Ones(1));
  Eigen::VectorXd dx;
  EXPECT_FALSE(eq.Solve(0.0, &dx));
  EXPECT_TRUE(eq.Marginals({0}).empty());
}

// Trilateration: a 2D point from ranges to known anchors, some of them gross outliers. Its
// cost is nonlinear in the point.
class Trilateration : public LeastSquaresProblem {
 public:
  Trilateration(std::vector<Eigen::Vector2d> anchors, std::vector<double> ranges, double sigma, RobustKernel kernel,
                Eigen::Vector2d start)
      : anchors_(std::move(anchors)), ranges_(std::move(ranges)), sigma_(sigma), kernel_(kernel), x_(start) {}
  double Linearise(BlockNormalEquations& eq) override {
    double cost = 0.0;
    for (std::size_t i = 0; i < anchors_.size(); ++i) {
      const Eigen::Vector2d d = x_ - anchors_[i];
      const double r = (d.norm() - ranges_[i]) / sigma_;
      Eigen::Matrix<double, 1, 2> j = d.transpose() / (d.norm() * sigma_);
      cost += 0.5 * kernel_.Rho(r * r);
      eq.Add(0, j, Eigen::Matrix<double, 1, 1>(r), kernel_.Weight(r * r));
    }
    return cost;
  }
  double Cost() const override {
    double cost = 0.0;
    for (std::size_t i = 0; i < anchors_.size(); ++i) {
      const double r = ((x_ - anchors_[i]).norm() - ranges_[i]) / sigma_;
      cost += 0.5 * kernel_.Rho(r * r);
    }
    return cost;
  }
  void Step(const Eigen::VectorXd& dx) override { x_ += dx.head<2>(); }
  void Save() override { saved_ = x_; }
  void Restore() override { x_ = saved_; }
  const Eigen::Vector2d& x() const { return x_; }

 private:
  std::vector<Eigen::Vector2d> anchors_;
  std::vector<double> ranges_;
  double sigma_;
  RobustKernel kernel_;
  Eigen::Vector2d x_, saved_;
};

// 12 anchors at random in a 20 m square and their ranges to `truth` with 1 cm noise, the first
// `outliers` of them 3 m long.
void RandomRanges(const Eigen::Vector2d& truth, int outliers, std::mt19937_64& rng,
                  std::vector<Eigen::Vector2d>* anchors, std::vector<double>* ranges) {
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> u(-10, 10);
  for (int i = 0; i < 12; ++i) {
    anchors->emplace_back(u(rng), u(rng));
    ranges->push_back((truth - anchors->back()).norm() + noise(rng) + (i < outliers ? 3.0 : 0.0));
  }
}

// Levenberg-Marquardt from far away finds the point; with gross outliers, plain least squares
// is pulled off and the Cauchy loss, started there, is not; at the optimum the gradient vanishes.
TEST(LevenbergMarquardt, FindsTheOptimumAndARobustLossResistsOutliers) {
  std::mt19937_64 rng(5);
  const Eigen::Vector2d truth(1.5, -2.0);
  int robust_better = 0;
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<Eigen::Vector2d> anchors;
    std::vector<double> ranges;
    RandomRanges(truth, 2, rng, &anchors, &ranges);
    BlockNormalEquations plain_eq({2}), robust_eq({2});
    plain_eq.Couple({0});
    robust_eq.Couple({0});
    plain_eq.Finalize();
    robust_eq.Finalize();
    Trilateration plain(anchors, ranges, 0.01, {}, {8.0, 8.0});
    const LevenbergMarquardtReport pr = MinimiseLevenbergMarquardt(plain, plain_eq);
    // Cauchy's loss is not convex: it starts where plain least squares ended, in its basin.
    Trilateration robust(anchors, ranges, 0.01, {RobustLoss::kCauchy, 2.0}, plain.x());
    const LevenbergMarquardtReport rr = MinimiseLevenbergMarquardt(robust, robust_eq);
    EXPECT_TRUE(pr.converged) << pr.stop;
    EXPECT_LT(pr.final_cost, pr.initial_cost);
    // At a minimum the gradient vanishes (relative to the cost's scale).
    EXPECT_LT(plain_eq.gradient().norm(), 1e-3 * std::sqrt(std::max(pr.final_cost, 1.0)));
    EXPECT_TRUE(rr.converged) << rr.stop;
    if ((robust.x() - truth).norm() < 0.02) ++robust_better;
    EXPECT_GT((plain.x() - truth).norm(), 0.05) << "the outliers pull plain least squares off";
  }
  EXPECT_GE(robust_better, 18);
}

// Started near its minimum with undamped_below on, the run ends where the Gauss-Newton step
// falls below step_tolerance, before taking it: within that tolerance of the minimum the
// default run finds, with eq holding the normal equations at the state returned, factorised
// undamped, so that the marginals are those of that state's H without another factorisation.
TEST(LevenbergMarquardt, AnUndampedRunStopsBeforeItsLastStepWithTheFactorAtTheStateItReturns) {
  std::mt19937_64 rng(11);
  const Eigen::Vector2d truth(1.5, -2.0);
  int stopped_before_a_step = 0;
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<Eigen::Vector2d> anchors;
    std::vector<double> ranges;
    RandomRanges(truth, 0, rng, &anchors, &ranges);
    const Eigen::Vector2d start = truth + Eigen::Vector2d(0.05, -0.03);
    BlockNormalEquations default_eq({2}), undamped_eq({2});
    default_eq.Couple({0});
    undamped_eq.Couple({0});
    default_eq.Finalize();
    undamped_eq.Finalize();
    LevenbergMarquardtOptions lm;
    lm.step_tolerance = 1e-6;
    Trilateration by_default(anchors, ranges, 0.01, {}, start);
    const LevenbergMarquardtReport dr = MinimiseLevenbergMarquardt(by_default, default_eq, lm);
    lm.undamped_below = lm.initial_lambda;
    Trilateration undamped(anchors, ranges, 0.01, {}, start);
    const LevenbergMarquardtReport ur = MinimiseLevenbergMarquardt(undamped, undamped_eq, lm);
    ASSERT_TRUE(dr.converged) << dr.stop;
    ASSERT_TRUE(ur.converged) << ur.stop;
    EXPECT_LT((undamped.x() - by_default.x()).cwiseAbs().maxCoeff(), lm.step_tolerance) << "trial " << trial;
    // The default run takes that last step, then linearises once more at its end.
    if (ur.stop == "step" && ur.steps_accepted < dr.steps_accepted && ur.iterations <= dr.iterations) {
      ++stopped_before_a_step;
    }
    // H at the state returned, by hand: sum over the ranges of J^T J.
    Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
    for (const Eigen::Vector2d& a : anchors) {
      const Eigen::Vector2d d = undamped.x() - a;
      const Eigen::RowVector2d j = d.transpose() / (d.norm() * 0.01);
      h += j.transpose() * j;
    }
    const std::vector<Eigen::MatrixXd> marginal = undamped_eq.Marginals({0});
    ASSERT_EQ(marginal.size(), 1u);
    EXPECT_LT((marginal[0] - h.inverse()).cwiseAbs().maxCoeff(), 1e-12 * h.inverse().cwiseAbs().maxCoeff() + 1e-18);
  }
  EXPECT_GE(stopped_before_a_step, 15);
}

}  // namespace
}  // namespace mapmesh
