#include "common/slam/submap_joiner.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "common/solver/least_squares.h"

namespace mapmesh {
namespace {

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
  Eigen::VectorXd h(3 + 2 * nl);
  Eigen::Matrix3d j_origin, j_end;
  const Pose2 motion = Between(origin, end, jacobian ? &j_origin : nullptr, jacobian ? &j_end : nullptr);
  h.head<3>() = motion.Vector();
  if (jacobian) {
    *jacobian = Eigen::MatrixXd::Zero(3 + 2 * nl, 6 + 2 * nl);
    jacobian->block<3, 3>(0, 0) = j_origin;
    jacobian->block<3, 3>(0, 3) = j_end;
  }
  Eigen::Matrix<double, 2, 3> j_pose;
  Eigen::Matrix2d j_point;
  for (Eigen::Index k = 0; k < nl; ++k) {
    h.segment<2>(3 + 2 * k) = origin.TransformTo(landmarks[k], jacobian ? &j_pose : nullptr,
                                                 jacobian ? &j_point : nullptr);
    if (jacobian) {
      jacobian->block<2, 3>(3 + 2 * k, 0) = j_pose;
      jacobian->block<2, 2>(3 + 2 * k, 6 + 2 * k) = j_point;
    }
  }
  return h;
}

void SubmapNormalEquations(const Eigen::MatrixXd& j, const Eigen::MatrixXd& info, const Eigen::VectorXd& e,
                           Eigen::MatrixXd* h, Eigen::VectorXd* g) {
  const Eigen::Index n = j.rows(), cols = j.cols(), nl = (n - 3) / 2;
  // m = info J, column block by column block: the frames' columns from the end-pose rows (both
  // frames) and the landmark rows (X_k only); each landmark's two columns from its own rows.
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n, cols);
  m.leftCols<6>().noalias() = info.leftCols<3>() * j.topLeftCorner<3, 6>();
  m.leftCols<3>().noalias() += info.rightCols(n - 3) * j.bottomLeftCorner(n - 3, 3);
  for (Eigen::Index i = 0; i < nl; ++i) {
    m.middleCols<2>(6 + 2 * i).noalias() = info.middleCols<2>(3 + 2 * i) * j.block<2, 2>(3 + 2 * i, 6 + 2 * i);
  }
  // h = J^T m, row block by row block the same way; g likewise from v = info e.
  const Eigen::VectorXd v = info * e;
  h->setZero(cols, cols);
  g->setZero(cols);
  h->topRows<6>().noalias() = j.topLeftCorner<3, 6>().transpose() * m.topRows<3>();
  h->topRows<3>().noalias() += j.bottomLeftCorner(n - 3, 3).transpose() * m.bottomRows(n - 3);
  g->head<6>().noalias() = j.topLeftCorner<3, 6>().transpose() * v.head<3>();
  g->head<3>().noalias() += j.bottomLeftCorner(n - 3, 3).transpose() * v.tail(n - 3);
  for (Eigen::Index i = 0; i < nl; ++i) {
    const Eigen::Matrix2d jl = j.block<2, 2>(3 + 2 * i, 6 + 2 * i);
    h->middleRows<2>(6 + 2 * i).noalias() = jl.transpose() * m.middleRows<2>(3 + 2 * i);
    g->segment<2>(6 + 2 * i).noalias() = jl.transpose() * v.segment<2>(3 + 2 * i);
  }
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
  // Variables of the shared least-squares kernel: the window's frames, then the landmarks, each
  // in increasing order.
  std::vector<std::size_t> frames;
  for (const auto& [k, p] : state->poses) frames.push_back(k);
  std::sort(frames.begin(), frames.end());
  std::vector<std::uint32_t> keys;
  for (const auto& [k, l] : state->landmarks) keys.push_back(k);
  std::sort(keys.begin(), keys.end());
  std::unordered_map<Var, int> index;
  std::vector<int> sizes;
  for (std::size_t k : frames) {
    index[PoseVar(k)] = static_cast<int>(sizes.size());
    sizes.push_back(3);
  }
  for (std::uint32_t k : keys) {
    index[k] = static_cast<int>(sizes.size());
    sizes.push_back(2);
  }
  BlockNormalEquations eq(std::move(sizes));
  // A submap factor couples its origin frame (unless it is the first, whose origin is fixed),
  // its end frame and its landmarks, in Linearise's order.
  std::vector<int> handles;
  for (const Factor& f : factors) {
    std::vector<int> vars;
    if (f.frame > 0) vars.push_back(index.at(PoseVar(f.frame)));
    vars.push_back(index.at(PoseVar(f.frame + 1)));
    for (std::uint32_t k : f.keys) vars.push_back(index.at(k));
    handles.push_back(eq.Couple(vars));
  }
  int prior_handle = -1;
  if (!prior_.vars.empty()) {
    std::vector<int> vars;
    for (Var v : prior_.vars) vars.push_back(index.at(v));
    prior_handle = eq.Couple(vars);
  }
  eq.Finalize();

  // Accumulates the normal equations at the state and returns the cost.
  auto assemble = [&]() {
    eq.SetZero();
    double cost = 0.0;
    for (std::size_t i = 0; i < factors.size(); ++i) {
      const Linearised lin = Linearise(factors[i], *state);
      cost += 0.5 * lin.r.squaredNorm();
      eq.Add(handles[i], lin.a, -lin.r);  // lin.r whitens z - h; the kernel's residual is h - z
    }
    if (prior_handle >= 0) {
      // d = x - x0 with angles wrapped; cost 1/2 d'Hd - g'd, whose gradient is Hd - g.
      const Eigen::VectorXd d = PriorOffset(*state);
      cost += 0.5 * d.dot(prior_.h * d) - prior_.g.dot(d);
      eq.AddInformation(prior_handle, prior_.h, prior_.h * d - prior_.g);
    }
    return cost;
  };
  auto apply = [&](const Eigen::VectorXd& dx, double scale) {
    for (std::size_t k : frames) {
      Pose2& p = state->poses.at(k);
      const int o = eq.offset(index.at(PoseVar(k)));
      p = p.Retract(scale * dx.segment<3>(o));
    }
    for (std::uint32_t k : keys) state->landmarks.at(k) += scale * dx.segment<2>(eq.offset(index.at(k)));
  };

  JoinedMap out;
  out.converged = false;
  double cost = assemble();
  Eigen::VectorXd dx;
  for (int it = 0; it < options_.max_iterations; ++it) {
    if (!eq.Solve(0.0, &dx)) break;
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

  // The covariances: the joint marginal of the landmarks and the newest frame, from the normal
  // equations at the final state.
  out.keys = keys;
  out.means.reserve(keys.size());
  for (std::uint32_t k : keys) out.means.push_back(state->landmarks.at(k));
  const std::size_t newest = frames.empty() ? 0 : frames.back();
  out.end = frames.empty() ? Pose2{} : state->poses.at(newest);
  const Eigen::Index nl = 2 * static_cast<Eigen::Index>(keys.size());
  std::vector<int> wanted;
  for (std::uint32_t k : keys) wanted.push_back(index.at(k));
  if (!frames.empty()) wanted.push_back(index.at(PoseVar(newest)));
  const Eigen::MatrixXd joint = eq.JointMarginal(wanted);
  if (joint.rows() != nl + (frames.empty() ? 0 : 3)) {
    out.converged = false;
    out.cov = Eigen::MatrixXd::Constant(nl, nl, std::numeric_limits<double>::quiet_NaN());
    return out;
  }
  out.cov = joint.topLeftCorner(nl, nl);
  if (!frames.empty()) {
    out.end_cov = joint.block<3, 3>(nl, nl);
    out.end_cross = joint.block(nl, 0, 3, nl);
  } else {
    out.end_cross = Eigen::MatrixXd::Zero(3, nl);
  }
  return out;
}

void SubmapJoiner::Add(const SubmapEstimate& submap) {
  Factor f = MakeFactor(submap, submaps_);
  Initialise(f, &state_);
  if (options_.relinearise_m > 0.0) history_.push_back(f);
  factors_.push_back(std::move(f));
  ++submaps_;
  last_ = Optimise(factors_, &state_);
  if (options_.relinearise_m > 0.0 && !prior_.vars.empty() &&
      submaps_ >= last_relinearised_ + static_cast<std::size_t>(options_.window) &&
      PriorDrift() > options_.relinearise_m) {
    Relinearise();
  }
  while (factors_.size() > static_cast<std::size_t>(options_.window)) Marginalise();
}

double SubmapJoiner::PriorDrift() const {
  const Eigen::VectorXd d = PriorOffset(state_);
  return d.size() == 0 ? 0.0 : d.cwiseAbs().maxCoeff();
}

void SubmapJoiner::Relinearise() {
  ++relinearisations_;
  last_relinearised_ = submaps_;
  for (const auto& [k, pose] : left_frames_) state_.poses[k] = pose;
  prior_ = Prior{};
  factors_.assign(history_.begin(), history_.end());
  last_ = Optimise(factors_, &state_);
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
    if (options_.relinearise_m > 0.0) left_frames_[a] = state_.poses.at(a);
    state_.poses.erase(a);
  }
  prior_.vars = std::move(kept_vars);
  prior_.x0 = xr;
  prior_.h = 0.5 * (hrr + hrr.transpose());
  prior_.g = br;
  factors_.pop_front();
}

}  // namespace mapmesh
