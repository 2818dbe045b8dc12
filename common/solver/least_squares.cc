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

BlockNormalEquations::BlockNormalEquations(std::vector<int> sizes, Factorisation factorisation)
    : sizes_(std::move(sizes)), factorisation_(factorisation) {
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
  // the factorisation would otherwise order at every Finalize. layout[k]: the k-th variable.
  std::vector<int> layout(static_cast<std::size_t>(variables()));
  for (int v = 0; v < variables(); ++v) layout[static_cast<std::size_t>(v)] = v;
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
      const int v = layout[static_cast<std::size_t>(k)] = order.indices()(k);
      offsets_[static_cast<std::size_t>(v)] = at;
      at += size(v);
    }
  }
  // H's upper triangle, built column by column in its compressed form. A block lies in the
  // columns of whichever of its two variables comes later in the layout (a diagonal block: the
  // variable's own columns, on and above the diagonal), so each variable's column block holds
  // its blocks' rows in the order of their row variables' offsets: sorting a variable's blocks
  // sorts every one of its columns, and each entry's place is known as it is written.
  std::vector<int> first_block(static_cast<std::size_t>(variables()) + 1, 0);  // per column variable
  auto column_var = [&](const Block& blk) { return offset(blk.a) <= offset(blk.b) ? blk.b : blk.a; };
  auto row_var = [&](const Block& blk) { return offset(blk.a) <= offset(blk.b) ? blk.a : blk.b; };
  for (const Block& blk : blocks_) ++first_block[static_cast<std::size_t>(column_var(blk)) + 1];
  for (int v = 0; v < variables(); ++v) {
    first_block[static_cast<std::size_t>(v) + 1] += first_block[static_cast<std::size_t>(v)];
  }
  std::vector<int> by_column(blocks_.size());  // block indices, grouped by column variable
  {
    std::vector<int> next(first_block.begin(), first_block.end() - 1);
    for (std::size_t i = 0; i < blocks_.size(); ++i) {
      by_column[static_cast<std::size_t>(next[static_cast<std::size_t>(column_var(blocks_[i]))]++)] = static_cast<int>(
          i);
    }
  }
  Eigen::Index nonzeros = 0;
  for (int v = 0; v < variables(); ++v) {
    const auto begin = by_column.begin() + first_block[static_cast<std::size_t>(v)];
    const auto end = by_column.begin() + first_block[static_cast<std::size_t>(v) + 1];
    std::sort(begin, end, [&](int x, int y) {
      return offset(row_var(blocks_[static_cast<std::size_t>(x)])) <
             offset(row_var(blocks_[static_cast<std::size_t>(y)]));
    });
    int rows = 0;  // per column of v, but its diagonal block's part
    for (auto it = begin; it != end; ++it) {
      const Block& blk = blocks_[static_cast<std::size_t>(*it)];
      if (blk.a != blk.b) rows += size(row_var(blk));
    }
    const int s = size(v);
    nonzeros += static_cast<Eigen::Index>(s) * rows + s * (s + 1) / 2;
  }
  h_ = Eigen::SparseMatrix<double>(dim_, dim_);
  h_.resizeNonZeros(nonzeros);
  int* outer = h_.outerIndexPtr();
  int* inner = h_.innerIndexPtr();
  std::fill(h_.valuePtr(), h_.valuePtr() + nonzeros, 0.0);
  positions_.assign(values_.size(), -1);
  diagonal_.resize(static_cast<std::size_t>(dim_));
  int at = 0;
  for (int v : layout) {  // the columns in order
    const int s = size(v);
    for (int cb = 0; cb < s; ++cb) {
      const int col = offset(v) + cb;
      outer[col] = at;
      for (int k = first_block[static_cast<std::size_t>(v)]; k < first_block[static_cast<std::size_t>(v) + 1]; ++k) {
        const Block& blk = blocks_[static_cast<std::size_t>(by_column[static_cast<std::size_t>(k)])];
        const int sa = size(blk.a);
        if (blk.a == blk.b) {  // rows 0 .. cb of the variable's own block (value (ra, cb))
          for (int ra = 0; ra <= cb; ++ra) {
            inner[at] = offset(v) + ra;
            positions_[static_cast<std::size_t>(blk.offset + cb * sa + ra)] = at++;
          }
          diagonal_[static_cast<std::size_t>(col)] = at - 1;
        } else if (blk.b == v) {  // rows of a, value (ra, cb)
          for (int ra = 0; ra < sa; ++ra) {
            inner[at] = offset(blk.a) + ra;
            positions_[static_cast<std::size_t>(blk.offset + cb * sa + ra)] = at++;
          }
        } else {  // rows of b (the block's columns), value (cb, rb): the transposed entry
          for (int rb = 0; rb < size(blk.b); ++rb) {
            inner[at] = offset(blk.b) + rb;
            positions_[static_cast<std::size_t>(blk.offset + rb * sa + cb)] = at++;
          }
        }
      }
    }
  }
  outer[dim_] = at;
  MAPMESH_CHECK(at == nonzeros && h_.isCompressed());
  factor_entries_ = SymbolicFactorEntries(layout);
  const double triangle = 0.5 * static_cast<double>(dim_) * static_cast<double>(dim_ + 1);
  dense_ = factorisation_ == Factorisation::kDense ||
           (factorisation_ == Factorisation::kAuto &&
            static_cast<double>(factor_entries_) >= kDenseFillShare * triangle);
  if (dense_) {
    dense_h_ = Eigen::MatrixXd::Zero(dim_, dim_);
  } else if (dim_ > 0) {
    llt_.analyzePattern(h_);
  }
  finalized_ = true;
}

Eigen::Index BlockNormalEquations::SymbolicFactorEntries(const std::vector<int>& layout) const {
  // Per variable (by its place in the layout): the later variables its column of L reaches.
  // Eliminating a variable joins its later neighbours into a clique, which its parent in the
  // elimination tree (the first of them) inherits.
  const auto n = layout.size();
  std::vector<int> place(n);
  for (std::size_t k = 0; k < n; ++k) place[static_cast<std::size_t>(layout[k])] = static_cast<int>(k);
  std::vector<std::vector<int>> later(n);
  for (const Block& blk : blocks_) {
    if (blk.a == blk.b) continue;
    const int pa = place[static_cast<std::size_t>(blk.a)], pb = place[static_cast<std::size_t>(blk.b)];
    later[static_cast<std::size_t>(std::min(pa, pb))].push_back(std::max(pa, pb));
  }
  Eigen::Index entries = 0;
  for (std::size_t k = 0; k < n; ++k) {
    std::vector<int>& l = later[k];
    std::sort(l.begin(), l.end());
    l.erase(std::unique(l.begin(), l.end()), l.end());
    const Eigen::Index s = size(layout[k]);
    Eigen::Index rows = 0;
    for (int j : l) rows += size(layout[static_cast<std::size_t>(j)]);
    entries += s * (s + 1) / 2 + s * rows;
    if (l.empty()) continue;
    std::vector<int>& parent = later[static_cast<std::size_t>(l.front())];
    parent.insert(parent.end(), l.begin() + 1, l.end());
    std::vector<int>().swap(l);
  }
  return entries;
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
  bool ok = false;
  if (dense_) {
    // h_'s upper triangle, column by column, into the dense matrix's lower one (its upper part
    // is unread).
    for (int col = 0; col < dim_; ++col) {
      for (Eigen::SparseMatrix<double>::InnerIterator it(h_, col); it; ++it) dense_h_(col, it.row()) = it.value();
    }
    dense_llt_.compute(dense_h_);
    ok = dense_llt_.info() == Eigen::Success;
  } else {
    llt_.factorize(h_);
    ok = llt_.info() == Eigen::Success;
  }
  factor_is_undamped_ = lambda == 0.0 && ok;
  return ok;
}

bool BlockNormalEquations::Solve(double lambda, Eigen::VectorXd* dx) {
  if (!Factorise(lambda)) return false;
  *dx = dense_ ? Eigen::VectorXd(dense_llt_.solve(-g_)) : Eigen::VectorXd(llt_.solve(-g_));
  return dx->allFinite();
}

void BlockNormalEquations::SolveUnitColumns(const std::vector<int>& vars, Eigen::MatrixXd* y) const {
  y->setZero();
  int col = 0;
  int first_row = dim_;  // the first row any of the unit columns has a one in
  for (int v : vars) {
    for (int i = 0; i < size(v); ++i) (*y)(offset(v) + i, col + i) = 1.0;
    first_row = std::min(first_row, offset(v));
    col += size(v);
  }
  if (dense_) {
    // L is lower triangular: rows above the first one stay zero, so only the trailing block is solved.
    const int rows = dim_ - first_row;
    dense_llt_.matrixLLT()
        .bottomRightCorner(rows, rows)
        .triangularView<Eigen::Lower>()
        .solveInPlace(y->bottomRows(rows));
  } else {
    llt_.matrixL().solveInPlace(*y);
  }
}

std::vector<Eigen::MatrixXd> BlockNormalEquations::Marginals(const std::vector<int>& vars) {
  std::vector<Eigen::MatrixXd> out;
  if (vars.empty()) return out;
  if (!factor_is_undamped_ && !Factorise(0.0)) return out;
  out.resize(vars.size());
  // With H = L L^T (H already in its fill-reducing layout), H^-1 = L^-T L^-1, so the block of
  // variables i and j is (L^-1 E_i)^T (L^-1 E_j): a forward substitution alone. A batch of
  // variables at a time, to bound the dense right-hand side, taken in the order of their
  // offsets: L^-1 E is zero above a batch's first unit row, which the dense path skips.
  std::vector<std::size_t> by_offset(vars.size());
  for (std::size_t i = 0; i < vars.size(); ++i) by_offset[i] = i;
  std::stable_sort(by_offset.begin(), by_offset.end(),
                   [&](std::size_t a, std::size_t b) { return offset(vars[a]) < offset(vars[b]); });
  constexpr std::size_t kBatchColumns = 64;
  Eigen::MatrixXd y(dim_, static_cast<Eigen::Index>(kBatchColumns));  // reused: no allocation per batch
  std::size_t first = 0;
  std::vector<int> batch_vars;
  while (first < vars.size()) {
    std::size_t last = first;
    int cols = 0;
    batch_vars.clear();
    while (last < vars.size() && (cols == 0 || cols + size(vars[by_offset[last]]) <= static_cast<int>(kBatchColumns))) {
      cols += size(vars[by_offset[last]]);
      batch_vars.push_back(vars[by_offset[last]]);
      ++last;
    }
    if (cols != y.cols()) y.resize(dim_, cols);
    SolveUnitColumns(batch_vars, &y);
    int col = 0;
    for (std::size_t k = first; k < last; ++k) {
      const int s = size(vars[by_offset[k]]);
      const Eigen::MatrixXd b = y.middleCols(col, s).transpose() * y.middleCols(col, s);
      out[by_offset[k]] = 0.5 * (b + b.transpose());
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
  Eigen::MatrixXd y(dim_, cols);
  SolveUnitColumns(vars, &y);
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
    // Damping below undamped_below is none: the Gauss-Newton step, whose size tells whether
    // the current state is already the minimum.
    const bool undamped = lambda < options.undamped_below;
    if (!eq.Solve(undamped ? 0.0 : lambda, &dx)) {
      if (lambda > 1e10) {
        report.stop = "not positive definite";
        break;
      }
      lambda = std::max(1e-6, lambda * 10.0);
      continue;
    }
    if (undamped && dx.cwiseAbs().maxCoeff() < options.step_tolerance) {
      // Within step_tolerance of the minimum of the model at the current state: stop there,
      // with its normal equations factorised undamped (Marginals needs no other).
      report.converged = true;
      report.stop = "step";
      break;
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
