#include "common/slam/submap_joiner.h"

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace mapmesh {
namespace {

// The Jacobian of R(theta)^T v with respect to theta.
Eigen::Vector2d DRotTranspose(double c, double s, const Eigen::Vector2d& v) {
  return {-s * v.x() + c * v.y(), -c * v.x() - s * v.y()};
}

// Where each variable of a system sits, and the system's size.
class Layout {
 public:
  int Offset(std::uint64_t var) const { return offsets_.at(var); }
  bool Has(std::uint64_t var) const { return offsets_.count(var) > 0; }
  int Add(std::uint64_t var, int size) {
    const auto [it, fresh] = offsets_.emplace(var, dim_);
    if (fresh) dim_ += size;
    return it->second;
  }
  int dim() const { return dim_; }

 private:
  std::unordered_map<std::uint64_t, int> offsets_;
  int dim_ = 0;
};

}  // namespace

std::optional<std::size_t> JoinedMap::Find(std::uint32_t key) const {
  const auto it = std::lower_bound(keys.begin(), keys.end(), key);
  if (it == keys.end() || *it != key) return std::nullopt;
  return static_cast<std::size_t>(it - keys.begin());
}

SubmapJoiner::SubmapJoiner(const JoinerOptions& options) : options_(options) {
  if (options.window < 1) throw std::invalid_argument("the joining window must hold at least one submap");
  if (options.max_iterations < 1) throw std::invalid_argument("joining needs at least one iteration");
}

SubmapJoiner::Factor SubmapJoiner::MakeFactor(const SubmapEstimate& s, std::size_t frame) {
  const Eigen::Index n = 3 + 2 * static_cast<Eigen::Index>(s.keys.size());
  if (s.x.size() != n || s.p.rows() != n || s.p.cols() != n) {
    throw std::invalid_argument("a submap needs 3 + 2 entries per landmark, and a covariance of that size");
  }
  if (!s.x.allFinite() || !s.p.allFinite()) throw std::invalid_argument("a submap holds a non-finite value");
  std::vector<std::uint32_t> sorted = s.keys;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
    throw std::invalid_argument("a submap names one landmark twice");
  }
  if (!s.p.isApprox(s.p.transpose(), 1e-9) && (s.p - s.p.transpose()).norm() > 1e-12) {
    throw std::invalid_argument("a submap's covariance is not symmetric");
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(s.p);
  if (llt.info() != Eigen::Success) throw std::invalid_argument("a submap's covariance is not positive definite");
  Factor f;
  f.frame = frame;
  f.z = s.x;
  f.z(2) = WrapAngle(f.z(2));
  // L^-1 with p = L L^T: whitens the residual, r = L^-1 e, so that |r|^2 = e' p^-1 e.
  f.sqrt_info = llt.matrixL().solve(Eigen::MatrixXd::Identity(n, n));
  f.keys = s.keys;
  return f;
}

void SubmapJoiner::Initialise(const Factor& f, State* state) {
  const Pose2 a = f.frame == 0 ? Pose2{} : state->poses.at(f.frame);
  if (!state->poses.count(f.frame + 1)) state->poses[f.frame + 1] = a * Pose2{f.z(0), f.z(1), f.z(2)};
  for (std::size_t j = 0; j < f.keys.size(); ++j) {
    if (!state->landmarks.count(f.keys[j])) {
      state->landmarks[f.keys[j]] = a.Apply(f.z.segment<2>(3 + 2 * static_cast<Eigen::Index>(j)));
    }
  }
}

Eigen::VectorXd PredictSubmap(const Pose2& origin, const Pose2& end, const std::vector<Eigen::Vector2d>& landmarks,
                              Eigen::MatrixXd* jacobian) {
  const auto nl = static_cast<Eigen::Index>(landmarks.size());
  const double c = std::cos(origin.theta), s = std::sin(origin.theta);
  Eigen::Matrix2d rt;
  rt << c, s, -s, c;
  const Eigen::Vector2d ta(origin.x, origin.y);
  const Eigen::Vector2d d = Eigen::Vector2d(end.x, end.y) - ta;
  Eigen::VectorXd h(3 + 2 * nl);
  h.head<2>() = rt * d;
  h(2) = WrapAngle(end.theta - origin.theta);
  for (Eigen::Index k = 0; k < nl; ++k) h.segment<2>(3 + 2 * k) = rt * (landmarks[k] - ta);
  if (jacobian) {
    Eigen::MatrixXd& j = *jacobian;
    j = Eigen::MatrixXd::Zero(3 + 2 * nl, 6 + 2 * nl);
    j.block<2, 2>(0, 0) = -rt;
    j.block<2, 1>(0, 2) = DRotTranspose(c, s, d);
    j(2, 2) = -1.0;
    j.block<2, 2>(0, 3) = rt;
    j(2, 5) = 1.0;
    for (Eigen::Index k = 0; k < nl; ++k) {
      j.block<2, 2>(3 + 2 * k, 0) = -rt;
      j.block<2, 1>(3 + 2 * k, 2) = DRotTranspose(c, s, landmarks[k] - ta);
      j.block<2, 2>(3 + 2 * k, 6 + 2 * k) = rt;
    }
  }
  return h;
}

SubmapJoiner::Linearised SubmapJoiner::Linearise(const Factor& f, const State& state) {
  const bool moving_origin = f.frame > 0;
  std::vector<Eigen::Vector2d> points;
  points.reserve(f.keys.size());
  for (std::uint32_t k : f.keys) points.push_back(state.landmarks.at(k));
  Eigen::MatrixXd j;
  const Eigen::VectorXd h = PredictSubmap(moving_origin ? state.poses.at(f.frame) : Pose2{},
                                          state.poses.at(f.frame + 1), points, &j);
  Eigen::VectorXd e = f.z - h;
  e(2) = WrapAngle(e(2));
  Linearised out;
  if (moving_origin) out.vars.push_back({PoseVar(f.frame), 3});
  out.vars.push_back({PoseVar(f.frame + 1), 3});
  for (std::uint32_t k : f.keys) out.vars.push_back({k, 2});
  const auto first = moving_origin ? 0 : 3;
  out.a = f.sqrt_info.triangularView<Eigen::Lower>() * j.rightCols(j.cols() - first);
  out.r = f.sqrt_info.triangularView<Eigen::Lower>() * e;
  return out;
}

Eigen::VectorXd SubmapJoiner::ValueOf(const State& state, Var var) {
  if (var & kPoseBit) return state.poses.at(var & ~kPoseBit).Vector();
  return state.landmarks.at(static_cast<std::uint32_t>(var));
}

Eigen::VectorXd SubmapJoiner::PriorOffset(const State& state) const {
  Eigen::VectorXd d(prior_.x0.size());
  Eigen::Index at = 0;
  for (Var v : prior_.vars) {
    const Eigen::VectorXd x = ValueOf(state, v);
    d.segment(at, x.size()) = x - prior_.x0.segment(at, x.size());
    if (v & kPoseBit) d(at + 2) = WrapAngle(d(at + 2));
    at += x.size();
  }
  return d;
}

namespace {

// Adds a linearised factor's normal equations (A'A dx = A'r) to a system: A'r to b, and each
// block of A'A through add_block(row, col, block).
template <typename Lin, typename OffsetOf, typename AddBlock>
void AddNormalEquations(const Lin& lin, const OffsetOf& offset_of, Eigen::VectorXd& b, const AddBlock& add_block) {
  const Eigen::MatrixXd hl = lin.a.transpose() * lin.a;
  const Eigen::VectorXd bl = lin.a.transpose() * lin.r;
  int ci = 0;
  for (const auto& [vi, si] : lin.vars) {
    const int oi = offset_of(vi);
    b.segment(oi, si) += bl.segment(ci, si);
    int cj = 0;
    for (const auto& [vj, sj] : lin.vars) {
      add_block(oi, offset_of(vj), hl.block(ci, cj, si, sj));
      cj += sj;
    }
    ci += si;
  }
}

}  // namespace

JoinedMap SubmapJoiner::Optimise(const std::deque<Factor>& factors, State* state) const {
  // Variables: the window's frames, then the landmarks, each in increasing order.
  std::vector<std::size_t> frames;
  for (const auto& [k, p] : state->poses) frames.push_back(k);
  std::sort(frames.begin(), frames.end());
  std::vector<std::uint32_t> keys;
  for (const auto& [k, l] : state->landmarks) keys.push_back(k);
  std::sort(keys.begin(), keys.end());
  Layout layout;
  for (std::size_t k : frames) layout.Add(PoseVar(k), 3);
  for (std::uint32_t k : keys) layout.Add(k, 2);
  const int n = layout.dim();

  auto offset_of = [&](Var v) { return layout.Offset(v); };

  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt;
  Eigen::SparseMatrix<double> h(n, n);
  Eigen::VectorXd b(n);
  // Builds H and b (H dx = b) at the state and returns the cost.
  auto assemble = [&]() {
    std::vector<Eigen::Triplet<double>> triplets;
    b.setZero();
    double cost = 0.0;
    auto add_block = [&](int row, int col, const Eigen::MatrixXd& block) {
      for (Eigen::Index r = 0; r < block.rows(); ++r) {
        for (Eigen::Index c = 0; c < block.cols(); ++c) triplets.emplace_back(row + r, col + c, block(r, c));
      }
    };
    for (const Factor& f : factors) {
      const Linearised lin = Linearise(f, *state);
      cost += 0.5 * lin.r.squaredNorm();
      AddNormalEquations(lin, offset_of, b, add_block);
    }
    if (!prior_.vars.empty()) {
      // d = x - x0 with angles wrapped; cost 1/2 d'Hd - g'd; b gets g - H d.
      const Eigen::VectorXd d = PriorOffset(*state);
      std::vector<int> offs, sizes;
      for (Var v : prior_.vars) {
        offs.push_back(layout.Offset(v));
        sizes.push_back((v & kPoseBit) ? 3 : 2);
      }
      const Eigen::VectorXd grad = prior_.g - prior_.h * d;
      cost += 0.5 * d.dot(prior_.h * d) - prior_.g.dot(d);
      int ri = 0;
      for (std::size_t i = 0; i < offs.size(); ++i) {
        b.segment(offs[i], sizes[i]) += grad.segment(ri, sizes[i]);
        int rj = 0;
        for (std::size_t k = 0; k < offs.size(); ++k) {
          add_block(offs[i], offs[k], prior_.h.block(ri, rj, sizes[i], sizes[k]));
          rj += sizes[k];
        }
        ri += sizes[i];
      }
    }
    h.setFromTriplets(triplets.begin(), triplets.end());
    return cost;
  };
  auto apply = [&](const Eigen::VectorXd& dx, double scale) {
    for (std::size_t k : frames) {
      Pose2& p = state->poses.at(k);
      const int o = layout.Offset(PoseVar(k));
      p = {p.x + scale * dx(o), p.y + scale * dx(o + 1), WrapAngle(p.theta + scale * dx(o + 2))};
    }
    for (std::uint32_t k : keys) state->landmarks.at(k) += scale * dx.segment<2>(layout.Offset(k));
  };

  JoinedMap out;
  out.converged = false;
  double cost = assemble();
  llt.analyzePattern(h);  // the pattern stays: the same factors over the same variables
  for (int it = 0; it < options_.max_iterations; ++it) {
    llt.factorize(h);
    if (llt.info() != Eigen::Success) break;
    const Eigen::VectorXd dx = llt.solve(b);
    ++out.iterations;
    // Gauss-Newton step, halved while it raises the cost (far from the minimum).
    const State before = *state;
    const double allowed = cost + 1e-12 * std::max(1.0, cost);
    double scale = 1.0, relative_drop = 0.0;
    bool accepted = false;
    for (int tries = 0; tries < 8 && !accepted; ++tries) {
      apply(dx, scale);
      const double next = assemble();
      if (next <= allowed) {
        relative_drop = (cost - next) / std::max(cost, 1e-300);
        cost = next;
        accepted = true;
      } else {
        *state = before;
        scale *= 0.5;
      }
    }
    if (!accepted) {
      cost = assemble();  // back at the state before the step: no descent left to find
      out.converged = dx.cwiseAbs().maxCoeff() < 1e3 * options_.tolerance;
      break;
    }
    if (scale * dx.cwiseAbs().maxCoeff() < options_.tolerance || relative_drop < options_.tolerance) {
      out.converged = true;
      break;
    }
  }

  // The covariances: columns of H^-1 for the landmarks and the newest frame.
  llt.factorize(h);
  out.keys = keys;
  out.means.reserve(keys.size());
  for (std::uint32_t k : keys) out.means.push_back(state->landmarks.at(k));
  const std::size_t newest = frames.empty() ? 0 : frames.back();
  out.end = frames.empty() ? Pose2{} : state->poses.at(newest);
  if (llt.info() != Eigen::Success) {
    out.converged = false;
    out.cov = Eigen::MatrixXd::Constant(2 * static_cast<Eigen::Index>(keys.size()),
                                        2 * static_cast<Eigen::Index>(keys.size()),
                                        std::numeric_limits<double>::quiet_NaN());
    return out;
  }
  const Eigen::Index nl = 2 * static_cast<Eigen::Index>(keys.size());
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, nl + (frames.empty() ? 0 : 3));
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const int o = layout.Offset(keys[i]);
    rhs(o, 2 * static_cast<Eigen::Index>(i)) = 1.0;
    rhs(o + 1, 2 * static_cast<Eigen::Index>(i) + 1) = 1.0;
  }
  int end_offset = 0;
  if (!frames.empty()) {
    end_offset = layout.Offset(PoseVar(newest));
    for (int r = 0; r < 3; ++r) rhs(end_offset + r, nl + r) = 1.0;
  }
  const Eigen::MatrixXd cols = llt.solve(rhs);
  out.cov.resize(nl, nl);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    out.cov.middleRows(2 * static_cast<Eigen::Index>(i), 2) = cols.block(layout.Offset(keys[i]), 0, 2, nl);
  }
  out.cov = 0.5 * (out.cov + out.cov.transpose()).eval();
  if (!frames.empty()) {
    const Eigen::Matrix3d ec = cols.block<3, 3>(end_offset, nl);
    out.end_cov = 0.5 * (ec + ec.transpose());
    out.end_cross = cols.block(end_offset, 0, 3, nl);
  } else {
    out.end_cross = Eigen::MatrixXd::Zero(3, nl);
  }
  return out;
}

void SubmapJoiner::Add(const SubmapEstimate& submap) {
  Factor f = MakeFactor(submap, submaps_);
  Initialise(f, &state_);
  factors_.push_back(std::move(f));
  ++submaps_;
  last_ = Optimise(factors_, &state_);
  while (factors_.size() > static_cast<std::size_t>(options_.window)) Marginalise();
}

JoinedMap SubmapJoiner::Solve(const SubmapEstimate* open) const {
  State state = state_;
  if (!open) return Optimise(factors_, &state);
  std::deque<Factor> factors = factors_;
  factors.push_back(MakeFactor(*open, submaps_));
  Initialise(factors.back(), &state);
  return Optimise(factors, &state);
}

void SubmapJoiner::Marginalise() {
  const Factor f = factors_.front();
  const std::size_t a = f.frame;
  const Linearised lin = Linearise(f, state_);

  // The variables: the prior's, then the factor's new ones.
  Layout layout;
  for (std::uint64_t v : prior_.vars) layout.Add(v, (v & kPoseBit) ? 3 : 2);
  for (const auto& [v, size] : lin.vars) layout.Add(v, size);
  const int n = layout.dim();
  Eigen::MatrixXd h = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd x(n);
  std::vector<std::uint64_t> vars = prior_.vars;
  for (const auto& [v, size] : lin.vars) {
    if (std::find(vars.begin(), vars.end(), v) == vars.end()) vars.push_back(v);
  }
  for (std::uint64_t v : vars) {
    const Eigen::VectorXd value = ValueOf(state_, v);
    x.segment(layout.Offset(v), value.size()) = value;
  }
  // The prior, at the current state (its variables are the layout's first rows, in order).
  if (!prior_.vars.empty()) {
    const Eigen::Index np = prior_.x0.size();
    const Eigen::VectorXd d = PriorOffset(state_);
    h.topLeftCorner(np, np) = prior_.h;
    b.head(np) = prior_.g - prior_.h * d;
  }
  // The factor.
  AddNormalEquations(
      lin, [&](Var v) { return layout.Offset(v); }, b,
      [&](int row, int col, const Eigen::MatrixXd& block) { h.block(row, col, block.rows(), block.cols()) += block; });

  // Eliminate the factor's origin frame X_a (nothing else refers to it now), by a Schur complement.
  std::vector<int> keep;
  std::vector<std::uint64_t> kept_vars;
  int elim = -1;
  if (a > 0) elim = layout.Offset(PoseVar(a));
  for (std::uint64_t v : vars) {
    if (a > 0 && v == PoseVar(a)) continue;
    kept_vars.push_back(v);
    const int o = layout.Offset(v);
    for (int r = 0; r < ((v & kPoseBit) ? 3 : 2); ++r) keep.push_back(o + r);
  }
  const auto nk = static_cast<Eigen::Index>(keep.size());
  Eigen::MatrixXd hrr(nk, nk);
  Eigen::VectorXd br(nk), xr(nk);
  for (Eigen::Index i = 0; i < nk; ++i) {
    br(i) = b(keep[i]);
    xr(i) = x(keep[i]);
    for (Eigen::Index k = 0; k < nk; ++k) hrr(i, k) = h(keep[i], keep[k]);
  }
  if (elim >= 0) {
    Eigen::MatrixXd hre(nk, 3);
    for (Eigen::Index i = 0; i < nk; ++i) hre.row(i) = h.block(keep[i], elim, 1, 3);
    const Eigen::Matrix3d hee = h.block<3, 3>(elim, elim);
    const Eigen::LDLT<Eigen::Matrix3d> ee(hee);
    hrr -= hre * ee.solve(hre.transpose());
    br -= hre * ee.solve(b.segment<3>(elim));
    state_.poses.erase(a);
  }
  prior_.vars = std::move(kept_vars);
  prior_.x0 = xr;
  prior_.h = 0.5 * (hrr + hrr.transpose());
  prior_.g = br;
  factors_.pop_front();
}

}  // namespace mapmesh
