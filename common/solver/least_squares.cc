#include "common/solver/least_squares.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/check.h"

namespace mapmesh {

double RobustKernel::Rho(double s) const {
  const double c2 = scale * scale;
  switch (loss) {
    case RobustLoss::kNone: return s;
    case RobustLoss::kHuber: return s <= c2 ? s : 2.0 * scale * std::sqrt(s) - c2;
    case RobustLoss::kCauchy: return c2 * std::log1p(s / c2);
  }
  return s;
}

double RobustKernel::Weight(double s) const {
  const double c2 = scale * scale;
  switch (loss) {
    case RobustLoss::kNone: return 1.0;
    case RobustLoss::kHuber: return s <= c2 ? 1.0 : scale / std::sqrt(s);
    case RobustLoss::kCauchy: return 1.0 / (1.0 + s / c2);
  }
  return 1.0;
}

BlockNormalEquations::BlockNormalEquations(std::vector<int> sizes) : sizes_(std::move(sizes)) {
  offsets_.reserve(sizes_.size());
  for (int s : sizes_) {
    MAPMESH_CHECK(s >= 1 && s <= 6, "variable sizes are 1-6");
    offsets_.push_back(dim_);
    dim_ += s;
  }
  g_ = Eigen::VectorXd::Zero(dim_);
}

int BlockNormalEquations::Couple(const std::vector<int>& vars) {
  MAPMESH_CHECK(!finalized_, "Couple before Finalize");
  Coupling c;
  c.vars = vars;
  int col = 0;
  for (int v : vars) {
    MAPMESH_CHECK(v >= 0 && v < variables(), "variable out of range");
    c.cols.push_back(col);
    col += size(v);
  }
  for (std::size_t i = 0; i < vars.size(); ++i) {
    for (std::size_t k = i; k < vars.size(); ++k) {
      MAPMESH_CHECK(k == i || vars[i] != vars[k], "a factor's variables are distinct");
      // The block (a, b) with a <= b, and which of the factor's variables gives its rows.
      const bool ordered = vars[i] <= vars[k];
      const int a = ordered ? vars[i] : vars[k], b = ordered ? vars[k] : vars[i];
      const std::uint64_t key = (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b);
      auto [it, fresh] = block_of_.try_emplace(key, static_cast<int>(blocks_.size()));
      if (fresh) {
        blocks_.push_back({a, b, static_cast<int>(values_.size())});
        values_.resize(values_.size() + static_cast<std::size_t>(size(a) * size(b)), 0.0);
      }
      c.terms.push_back({it->second, ordered ? c.cols[i] : c.cols[k], ordered ? c.cols[k] : c.cols[i]});
    }
  }
  couplings_.push_back(std::move(c));
  return static_cast<int>(couplings_.size()) - 1;
}

void BlockNormalEquations::Finalize() {
  MAPMESH_CHECK(!finalized_, "Finalize once");
  // Every variable's diagonal block is in the pattern, so that damping always has a place.
  for (int v = 0; v < variables(); ++v) {
    const std::uint64_t key = (static_cast<std::uint64_t>(v) << 32) | static_cast<std::uint32_t>(v);
    if (block_of_.try_emplace(key, static_cast<int>(blocks_.size())).second) {
      blocks_.push_back({v, v, static_cast<int>(values_.size())});
      values_.resize(values_.size() + static_cast<std::size_t>(size(v) * size(v)), 0.0);
    }
  }
  // The variables' layout: an approximate minimum degree order of the block pattern (Amestoy,
  // Davis & Duff), a few times fewer nodes and tens of times fewer edges than the scalar pattern
  // the factorisation would otherwise order at every Finalize.
  if (variables() > 1) {
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(2 * blocks_.size());
    for (const Block& blk : blocks_) {
      entries.emplace_back(blk.a, blk.b, 1.0);
      if (blk.a != blk.b) entries.emplace_back(blk.b, blk.a, 1.0);
    }
    Eigen::SparseMatrix<double> pattern(variables(), variables());
    pattern.setFromTriplets(entries.begin(), entries.end());
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order;  // order(k): the k-th variable
    Eigen::AMDOrdering<int>()(pattern, order);
    int at = 0;
    for (int k = 0; k < variables(); ++k) {
      const int v = order.indices()(k);
      offsets_[static_cast<std::size_t>(v)] = at;
      at += size(v);
    }
  }
  // The upper triangle's entries, column by column.
  // A block's entry (ra, cb) is H's (offset(a) + ra, offset(b) + cb) and, H being symmetric,
  // the transposed one: of the two, the one on or above the diagonal (a diagonal block's entries
  // below it are left out, their transposes being in the block).
  auto upper = [&](const Block& blk, int ra, int cb) -> std::pair<int, int> {
    const int row = offset(blk.a) + ra, col = offset(blk.b) + cb;
    if (blk.a == blk.b) return row <= col ? std::pair{row, col} : std::pair{-1, -1};
    return row <= col ? std::pair{row, col} : std::pair{col, row};
  };
  std::vector<std::vector<int>> rows(static_cast<std::size_t>(dim_));
  for (const Block& blk : blocks_) {
    for (int cb = 0; cb < size(blk.b); ++cb) {
      for (int ra = 0; ra < size(blk.a); ++ra) {
        const auto [row, col] = upper(blk, ra, cb);
        if (row >= 0) rows[static_cast<std::size_t>(col)].push_back(row);
      }
    }
  }
  Eigen::VectorXi per_column(dim_);
  for (int c = 0; c < dim_; ++c) {
    std::sort(rows[static_cast<std::size_t>(c)].begin(), rows[static_cast<std::size_t>(c)].end());
    per_column(c) = static_cast<int>(rows[static_cast<std::size_t>(c)].size());
  }
  h_.resize(dim_, dim_);
  h_.reserve(per_column);
  for (int c = 0; c < dim_; ++c) {
    for (int r : rows[static_cast<std::size_t>(c)]) h_.insert(r, c) = 0.0;
  }
  h_.makeCompressed();
  // Where each block entry lands among h_'s values.
  auto position = [&](int row, int col) {
    const int* begin = h_.innerIndexPtr() + h_.outerIndexPtr()[col];
    const int* end = h_.innerIndexPtr() + h_.outerIndexPtr()[col + 1];
    const int* it = std::lower_bound(begin, end, row);
    MAPMESH_CHECK(it != end && *it == row);
    return static_cast<int>(it - h_.innerIndexPtr());
  };
  positions_.assign(values_.size(), -1);
  for (const Block& blk : blocks_) {
    const int sa = size(blk.a);
    for (int cb = 0; cb < size(blk.b); ++cb) {
      for (int ra = 0; ra < sa; ++ra) {
        const auto [row, col] = upper(blk, ra, cb);
        if (row >= 0) positions_[static_cast<std::size_t>(blk.offset + cb * sa + ra)] = position(row, col);
      }
    }
  }
  diagonal_.resize(static_cast<std::size_t>(dim_));
  for (int i = 0; i < dim_; ++i) diagonal_[static_cast<std::size_t>(i)] = position(i, i);
  if (dim_ > 0) llt_.analyzePattern(h_);
  finalized_ = true;
}

void BlockNormalEquations::SetZero() {
  std::fill(values_.begin(), values_.end(), 0.0);
  g_.setZero();
  factor_is_undamped_ = false;
}

void BlockNormalEquations::Add(int handle, const Eigen::Ref<const Eigen::MatrixXd>& j,
                               const Eigen::Ref<const Eigen::VectorXd>& r, double w) {
  const Coupling& c = couplings_[static_cast<std::size_t>(handle)];
  for (std::size_t i = 0; i < c.vars.size(); ++i) {
    g_.segment(offset(c.vars[i]), size(c.vars[i])) += w * j.middleCols(c.cols[i], size(c.vars[i])).transpose() * r;
  }
  for (const Term& t : c.terms) {
    const Block& blk = blocks_[static_cast<std::size_t>(t.block)];
    const int sa = size(blk.a), sb = size(blk.b);
    Eigen::Map<Eigen::MatrixXd> dst(values_.data() + blk.offset, sa, sb);
    dst.noalias() += w * j.middleCols(t.col_a, sa).transpose() * j.middleCols(t.col_b, sb);
  }
  factor_is_undamped_ = false;
}

void BlockNormalEquations::AddInformation(int handle, const Eigen::Ref<const Eigen::MatrixXd>& h,
                                          const Eigen::Ref<const Eigen::VectorXd>& g) {
  const Coupling& c = couplings_[static_cast<std::size_t>(handle)];
  for (std::size_t i = 0; i < c.vars.size(); ++i) {
    g_.segment(offset(c.vars[i]), size(c.vars[i])) += g.segment(c.cols[i], size(c.vars[i]));
  }
  for (const Term& t : c.terms) {
    const Block& blk = blocks_[static_cast<std::size_t>(t.block)];
    const int sa = size(blk.a), sb = size(blk.b);
    Eigen::Map<Eigen::MatrixXd> dst(values_.data() + blk.offset, sa, sb);
    dst += h.block(t.col_a, t.col_b, sa, sb);
  }
  factor_is_undamped_ = false;
}

void BlockNormalEquations::Assemble(double lambda) {
  double* h = h_.valuePtr();
  std::fill(h, h + h_.nonZeros(), 0.0);
  for (std::size_t i = 0; i < values_.size(); ++i) {
    if (positions_[i] >= 0) h[positions_[i]] += values_[i];
  }
  if (lambda > 0) {
    for (int p : diagonal_) h[p] += lambda * std::max(h[p], 1e-12);
  }
}

bool BlockNormalEquations::Factorise(double lambda) {
  MAPMESH_CHECK(finalized_, "Finalize before solving");
  Assemble(lambda);
  llt_.factorize(h_);
  factor_is_undamped_ = lambda == 0.0 && llt_.info() == Eigen::Success;
  return llt_.info() == Eigen::Success;
}

bool BlockNormalEquations::Solve(double lambda, Eigen::VectorXd* dx) {
  if (!Factorise(lambda)) return false;
  *dx = llt_.solve(-g_);
  return dx->allFinite();
}

std::vector<Eigen::MatrixXd> BlockNormalEquations::Marginals(const std::vector<int>& vars) {
  std::vector<Eigen::MatrixXd> out;
  if (vars.empty()) return out;
  if (!factor_is_undamped_ && !Factorise(0.0)) return out;
  out.reserve(vars.size());
  // With H = L L^T (H already in its fill-reducing layout), H^-1 = L^-T L^-1, so the block of
  // variables i and j is (L^-1 E_i)^T (L^-1 E_j): a forward substitution alone, which skips the zeros above each
  // unit column (most of them, the fill of a column being what the elimination reaches from it).
  // A batch of variables at a time, to bound the dense right-hand side.
  constexpr std::size_t kBatchColumns = 64;
  Eigen::MatrixXd y(dim_, static_cast<Eigen::Index>(kBatchColumns));  // reused: no allocation per batch
  std::size_t first = 0;
  while (first < vars.size()) {
    std::size_t last = first;
    int cols = 0;
    while (last < vars.size() && (cols == 0 || cols + size(vars[last]) <= static_cast<int>(kBatchColumns))) {
      cols += size(vars[last]);
      ++last;
    }
    if (cols > y.cols()) y.resize(dim_, cols);
    auto batch = y.leftCols(cols);
    batch.setZero();
    int col = 0;
    for (std::size_t k = first; k < last; ++k) {
      for (int i = 0; i < size(vars[k]); ++i) batch(offset(vars[k]) + i, col + i) = 1.0;
      col += size(vars[k]);
    }
    llt_.matrixL().solveInPlace(batch);
    col = 0;
    for (std::size_t k = first; k < last; ++k) {
      const int s = size(vars[k]);
      const Eigen::MatrixXd b = batch.middleCols(col, s).transpose() * batch.middleCols(col, s);
      out.push_back(0.5 * (b + b.transpose()));
      col += s;
    }
    first = last;
  }
  return out;
}

Eigen::MatrixXd BlockNormalEquations::JointMarginal(const std::vector<int>& vars) {
  if (vars.empty()) return {};
  if (!factor_is_undamped_ && !Factorise(0.0)) return {};
  int cols = 0;
  for (int v : vars) cols += size(v);
  // As Marginals: Y = L^-1 E, and the covariance of the chosen variables is Y^T Y.
  Eigen::MatrixXd y = Eigen::MatrixXd::Zero(dim_, cols);
  int col = 0;
  for (int v : vars) {
    for (int i = 0; i < size(v); ++i) y(offset(v) + i, col + i) = 1.0;
    col += size(v);
  }
  llt_.matrixL().solveInPlace(y);
  const Eigen::MatrixXd cov = y.transpose() * y;
  return 0.5 * (cov + cov.transpose());
}

LevenbergMarquardtReport MinimiseLevenbergMarquardt(LeastSquaresProblem& problem, BlockNormalEquations& eq,
                                                    const LevenbergMarquardtOptions& options) {
  LevenbergMarquardtReport report;
  double lambda = options.initial_lambda;
  eq.SetZero();
  double cost = problem.Linearise(eq);
  report.initial_cost = cost;
  report.iterations = 1;
  if (eq.dim() == 0) {  // nothing to move
    report.converged = true;
    report.stop = "step";
    report.final_cost = cost;
    return report;
  }
  bool linearised_here = true;  // eq holds the normal equations at the current state
  report.stop = "iterations";
  Eigen::VectorXd dx;
  while (true) {
    if (!eq.Solve(lambda, &dx)) {
      if (lambda > 1e10) {
        report.stop = "not positive definite";
        break;
      }
      lambda = std::max(1e-6, lambda * 10.0);
      continue;
    }
    problem.Save();
    problem.Step(dx);
    const double next = problem.Cost();
    if (std::isfinite(next) && next <= cost) {
      ++report.steps_accepted;
      const double drop = (cost - next) / std::max(cost, std::numeric_limits<double>::min());
      cost = next;
      lambda = std::max(lambda / 3.0, 1e-12);
      linearised_here = false;
      if (drop < options.function_tolerance) {
        report.converged = true;
        report.stop = "cost";
        break;
      }
      if (dx.cwiseAbs().maxCoeff() < options.step_tolerance && lambda < 1.0) {  // a small step, not a damped one
        report.converged = true;
        report.stop = "step";
        break;
      }
      if (report.iterations >= options.max_iterations) break;
      eq.SetZero();
      cost = problem.Linearise(eq);
      ++report.iterations;
      linearised_here = true;
    } else {
      problem.Restore();
      // A step too small to change anything that still does not lower the cost: at the minimum
      // to rounding when the undamped (Gauss-Newton) step promises no real decrease either,
      // 1/2 g^T H^-1 g; else damping alone made the step small.
      if (dx.cwiseAbs().maxCoeff() < options.step_tolerance || lambda > 1e12) {
        Eigen::VectorXd gn;
        const bool solved = eq.Solve(0.0, &gn);
        const double promised = solved ? -0.5 * eq.gradient().dot(gn) : std::numeric_limits<double>::infinity();
        // (Whitened costs are dimensionless: 1e-18 is rounding, whatever the problem.)
        report.converged = promised <= 10.0 * options.function_tolerance * cost + 1e-18;
        report.stop = report.converged ? "step" : "no descent";
        break;
      }
      lambda *= 4.0;
    }
  }
  if (!linearised_here) {
    eq.SetZero();
    cost = problem.Linearise(eq);
  }
  report.final_cost = cost;
  return report;
}

}  // namespace mapmesh
