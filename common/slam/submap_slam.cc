#include "common/slam/submap_slam.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>

#include "common/geometry/rigid_fit.h"

namespace mapmesh {
namespace {

void AddStats(MapperStats* sum, const MapperStats& s) {
  sum->offered += s.offered;
  sum->associated += s.associated;
  sum->initialised += s.initialised;
  sum->tentative += s.tentative;
  sum->rejected_gate += s.rejected_gate;
  sum->ambiguous += s.ambiguous;
  sum->unidentified += s.unidentified;
  sum->out_of_range += s.out_of_range;
  sum->invalid += s.invalid;
  sum->failed_updates += s.failed_updates;
}

// The covariance made exactly symmetric, its eigenvalues no less than (30 um)^2 (or rad^2): a
// robot that has barely moved since the submap began has an almost zero pose covariance, and
// rounding in a long filter can leave a tiny negative eigenvalue; the inverse of either would
// swamp every other submap's information in the joint solve.
Eigen::MatrixXd Regularised(const Eigen::MatrixXd& p) {
  constexpr double kFloor = 1e-9;
  const Eigen::MatrixXd q = 0.5 * (p + p.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(q);
  if (es.info() == Eigen::Success && es.eigenvalues().minCoeff() >= kFloor) return q;
  if (es.info() != Eigen::Success) return q + kFloor * Eigen::MatrixXd::Identity(q.rows(), q.cols());
  const Eigen::VectorXd clamped = es.eigenvalues().cwiseMax(kFloor);
  return es.eigenvectors() * clamped.asDiagonal() * es.eigenvectors().transpose();
}

}  // namespace

SubmapSlam::SubmapSlam(const FilterNoise& noise, const LocalSlamOptions& options)
    : noise_(noise),
      options_(options),
      submap_(options.submaps),
      known_association_(options.association.method == AssociationMethod::kKnown),
      joiner_(options.submaps.join) {
  options_.filter = SlamMethod::kCekf;
  current_ = std::make_unique<LocalSlam>(noise_, options_);
}

void SubmapSlam::Predict(const OdometryControl& u, double dt) {
  current_->Predict(u, dt);
  travelled_m_ += std::abs(u.v_mps) * dt;
  elapsed_s_ += dt;
  fresh_ = false;
}

bool SubmapSlam::ShouldClose() const {
  if (elapsed_s_ == 0.0) return false;  // nothing has moved the robot in it yet
  if (submap_.distance_m > 0 && travelled_m_ >= submap_.distance_m) return true;
  if (submap_.duration_s > 0 && elapsed_s_ >= submap_.duration_s) return true;
  if (submap_.landmarks > 0 && current_->size() >= static_cast<std::size_t>(submap_.landmarks)) return true;
  if (submap_.heading_sigma_deg > 0 &&
      std::sqrt(std::max(0.0, current_->pose_cov()(2, 2))) >= DegToRad(submap_.heading_sigma_deg)) {
    return true;
  }
  return false;
}

void SubmapSlam::Observe(const std::vector<Observation>& obs, double stamp) {
  // A submap ends before the scan that finds it due, so that the scan is applied from a fresh
  // origin rather than linearised at a pose the submap has grown unsure of.
  if (ShouldClose()) Close();
  if (!opened_s_) opened_s_ = stamp;
  last_stamp_s_ = stamp;
  current_->Observe(obs, stamp);
  fresh_ = false;
}

std::vector<std::int64_t> SubmapSlam::Keys(const Eigen::VectorXd& x, const Eigen::MatrixXd& p,
                                           const std::vector<LandmarkId>& ids) const {
  const std::size_t n = ids.size();
  std::vector<std::int64_t> keys(n, -1);
  std::int64_t next = next_key_;
  if (joiner_.submaps() == 0) {
    for (std::size_t i = 0; i < n; ++i) keys[i] = known_association_ ? static_cast<std::int64_t>(ids[i]) : next++;
    return keys;
  }
  const JoinedMap& j = joiner_.last();
  const std::size_t nj = j.keys.size();
  std::vector<Eigen::Vector2d> rel;
  std::vector<Eigen::Matrix2d> rel_cov;
  Relative(&rel, &rel_cov);
  auto d2 = [&](std::size_t i, std::size_t k) {
    const auto row = static_cast<Eigen::Index>(3 + 2 * i);
    const Eigen::Vector2d d = x.segment<2>(row) - rel[k];
    return d.dot((p.block<2, 2>(row, row) + rel_cov[k]).ldlt().solve(d));
  };
  if (known_association_) {
    // A landmark the joined map holds must agree with it: one that does not (an outlier that
    // started it in this submap, where nothing could gate it) is left out.
    for (std::size_t i = 0; i < n; ++i) {
      const std::optional<std::size_t> k = j.Find(ids[i]);
      if (!k || d2(i, *k) < submap_.association_gate) keys[i] = ids[i];
    }
    return keys;
  }
  std::vector<double> best_d2(n, std::numeric_limits<double>::infinity());
  std::vector<int> best(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    int inside = 0;
    for (std::size_t k = 0; k < nj; ++k) {
      const double e = d2(i, k);
      if (!(e < submap_.association_gate)) continue;
      ++inside;
      if (e < best_d2[i]) {
        best_d2[i] = e;
        best[i] = static_cast<int>(k);
      }
    }
    if (inside > 1) best[i] = -2;  // ambiguous: left out
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (best[i] == -2) continue;
    if (best[i] < 0) {
      keys[i] = next++;
      continue;
    }
    // Two landmarks of the submap on one joined landmark: the nearer keeps it.
    bool nearest = true;
    for (std::size_t o = 0; o < n; ++o) {
      if (o != i && best[o] == best[i] && (best_d2[o] < best_d2[i] || (best_d2[o] == best_d2[i] && o < i))) {
        nearest = false;
      }
    }
    if (nearest) keys[i] = j.keys[static_cast<std::size_t>(best[i])];
  }
  return keys;
}

void SubmapSlam::Relative(std::vector<Eigen::Vector2d>* rel, std::vector<Eigen::Matrix2d>* rel_cov) const {
  const JoinedMap& j = joiner_.last();
  const std::size_t nj = j.keys.size();
  rel->resize(nj);
  rel_cov->resize(nj);
  for (std::size_t k = 0; k < nj; ++k) {
    Eigen::MatrixXd jac;
    const Eigen::VectorXd h = PredictSubmap(j.end, j.end, {j.means[k]}, &jac);
    (*rel)[k] = h.segment<2>(3);
    const Eigen::Matrix<double, 2, 3> jx = jac.block<2, 3>(3, 0);
    const Eigen::Matrix2d jl = jac.block<2, 2>(3, 6);
    const Eigen::Matrix<double, 3, 2> xl = j.end_cross.block<3, 2>(0, 2 * static_cast<Eigen::Index>(k));
    (*rel_cov)[k] = jx * j.end_cov * jx.transpose() + jl * j.Cov(k) * jl.transpose() + jx * xl * jl.transpose() +
                    jl * xl.transpose() * jx.transpose();
  }
}

bool SubmapSlam::Replace(Eigen::VectorXd* x, Eigen::MatrixXd* p, const std::vector<LandmarkId>& ids) const {
  if (!submap_.divergence_guard || !known_association_ || joiner_.submaps() == 0) return false;
  const JoinedMap& j = joiner_.last();
  std::vector<Eigen::Vector2d> rel;
  std::vector<Eigen::Matrix2d> rel_cov;
  Relative(&rel, &rel_cov);
  // The landmarks both hold: (row of x, index in the joined map).
  std::vector<std::pair<Eigen::Index, std::size_t>> shared;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (const std::optional<std::size_t> k = j.Find(ids[i]))
      shared.emplace_back(3 + 2 * static_cast<Eigen::Index>(i), *k);
  }
  auto disagreeing = [&](const Eigen::VectorXd& xs, const Eigen::MatrixXd& ps) {
    std::size_t n = 0;
    for (const auto& [row, k] : shared) {
      const Eigen::Vector2d d = xs.segment<2>(row) - rel[k];
      n += d.dot((ps.block<2, 2>(row, row) + rel_cov[k]).ldlt().solve(d)) < submap_.association_gate ? 0 : 1;
    }
    return n;
  };
  const std::size_t bad = disagreeing(*x, *p);
  if (shared.size() < 3 || bad < 2 || 2 * bad <= shared.size()) return false;
  std::vector<Eigen::Vector2d> src, dst;
  for (const auto& [row, k] : shared) {
    src.push_back(x->segment<2>(row));
    dst.push_back(rel[k]);
  }
  // Landmarks closer together than this fix no heading: a fit of a cluster 0.3 m across turns a
  // submap by a radian on centimetres of noise (MRCLAM's landmarks 13 and 14, say).
  constexpr double kMinSpanM = 1.0;
  double span = 0.0;
  for (const Eigen::Vector2d& a : dst) {
    for (const Eigen::Vector2d& b : dst) span = std::max(span, (a - b).norm());
  }
  if (span < kMinSpanM) return false;
  const std::optional<Pose2> t = FitRigid2D(src, dst);
  if (!t) return false;
  // x' = T(x): the end pose composed, every landmark moved; J = dx'/dx, G = dx'/d(tx, ty, theta).
  const Eigen::Index n = x->size();
  Eigen::VectorXd moved = *x;
  Eigen::MatrixXd jac = Eigen::MatrixXd::Identity(n, n), g = Eigen::MatrixXd::Zero(n, 3);
  const double c = std::cos(t->theta), s = std::sin(t->theta);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  for (Eigen::Index row = 0; row < n; row += (row == 0 ? 3 : 2)) {
    const Eigen::Vector2d q = t->Apply(Eigen::Vector2d(x->segment<2>(row)));
    moved.segment<2>(row) = q;
    jac.block<2, 2>(row, row) = r;
    g.block<2, 2>(row, 0).setIdentity();
    g.block<2, 1>(row, 2) = Eigen::Vector2d(-(q.y() - t->y), q.x() - t->x);
  }
  moved(2) = WrapAngle((*x)(2) + t->theta);
  g(2, 2) = 1.0;
  const Eigen::MatrixXd rotated = jac * *p * jac.transpose();
  if (4 * disagreeing(moved, rotated) > shared.size()) return false;  // no placement agrees: leave it
  *x = moved;
  *p = rotated + g * Eigen::Vector3d(25.0, 25.0, 4.0).asDiagonal() * g.transpose();
  return true;
}

std::optional<SubmapEstimate> SubmapSlam::OpenSubmap(bool* replaced) const {
  Eigen::VectorXd x;
  Eigen::MatrixXd p;
  std::vector<LandmarkId> ids;
  current_->FullState(&x, &p, &ids);
  if (ids.empty() && elapsed_s_ == 0.0) return std::nullopt;
  const bool moved = Replace(&x, &p, ids);
  if (replaced) *replaced = moved;
  const std::vector<std::int64_t> keys = Keys(x, p, ids);
  std::vector<Eigen::Index> rows = {0, 1, 2};
  SubmapEstimate s;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (keys[i] < 0) continue;
    s.keys.push_back(static_cast<std::uint32_t>(keys[i]));
    rows.push_back(static_cast<Eigen::Index>(3 + 2 * i));
    rows.push_back(static_cast<Eigen::Index>(4 + 2 * i));
  }
  const auto n = static_cast<Eigen::Index>(rows.size());
  s.x.resize(n);
  Eigen::MatrixXd q(n, n);
  for (Eigen::Index r = 0; r < n; ++r) {
    s.x(r) = x(rows[r]);
    for (Eigen::Index c = 0; c < n; ++c) q(r, c) = p(rows[r], rows[c]);
  }
  s.p = Regularised(q);
  return s;
}

void SubmapSlam::Close() {
  bool replaced = false;
  if (const std::optional<SubmapEstimate> s = OpenSubmap(&replaced)) {
    diverged_ += replaced ? 1 : 0;
    joiner_.Add(*s);
    for (std::uint32_t k : s->keys) next_key_ = std::max(next_key_, k + 1);
    closed_.push_back({*s, opened_s_.value_or(last_stamp_s_), last_stamp_s_});
  }
  opened_s_.reset();
  AddStats(&closed_stats_, current_->stats());
  current_ = std::make_unique<LocalSlam>(noise_, options_);
  travelled_m_ = 0.0;
  elapsed_s_ = 0.0;
  fresh_ = false;
}

LandmarkMap SubmapSlam::Map() const {
  if (fresh_) return map_;
  const std::optional<SubmapEstimate> open = OpenSubmap();
  JoinedMap joined;
  if (open) {
    joined = joiner_.Solve(&*open);
  } else if (joiner_.submaps() > 0) {
    joined = joiner_.last();
  } else {
    joined = JoinedMap{};
  }
  map_ = JoinedLandmarkMap(joined, known_association_);
  fresh_ = true;
  return map_;
}

Pose2 SubmapSlam::pose() const {
  if (joiner_.submaps() == 0) return current_->pose();
  return joiner_.last().end * current_->pose();
}

Eigen::Matrix3d SubmapSlam::pose_cov() const {
  if (joiner_.submaps() == 0) return current_->pose_cov();
  // The open submap is independent of the closed ones: the origin's and the pose's errors add.
  Eigen::Matrix3d jx, jq;
  Compose(joiner_.last().end, current_->pose(), &jx, &jq);
  return jx * joiner_.last().end_cov * jx.transpose() + jq * current_->pose_cov() * jq.transpose();
}

std::size_t SubmapSlam::size() const {
  if (joiner_.submaps() == 0) return current_->size();
  if (!known_association_) return Map().size();
  Eigen::VectorXd x;
  Eigen::MatrixXd p;
  std::vector<LandmarkId> ids;
  current_->FullState(&x, &p, &ids);
  std::size_t n = joiner_.landmarks();
  for (LandmarkId id : ids) n += joiner_.last().Find(id) ? 0 : 1;
  return n;
}

const MapperStats& SubmapSlam::stats() const {
  stats_ = closed_stats_;
  AddStats(&stats_, current_->stats());
  stats_.diverged = diverged_;
  return stats_;
}

LandmarkMap JoinedLandmarkMap(const JoinedMap& joined, bool signatures) {
  LandmarkMap map;
  map.landmarks.reserve(joined.keys.size());
  for (std::size_t i = 0; i < joined.keys.size(); ++i) {
    Landmark l;
    l.id = joined.keys[i];
    l.signature = signatures ? static_cast<std::int32_t>(l.id) : -1;
    l.mean = joined.means[i];
    l.cov = joined.Cov(i);
    map.landmarks.push_back(l);
  }
  map.shape_sigma_m = ShapeSigma(map, [&](std::size_t i, std::size_t j) { return joined.CrossCov(i, j); });
  return map;
}

std::optional<WireSubmap> ToWire(const SubmapEstimate& estimate, const SubmapId& id, double opened_s, double closed_s) {
  WireSubmap w;
  w.id = id;
  w.opened_s = opened_s;
  w.closed_s = closed_s;
  w.keys = estimate.keys;
  w.x = estimate.x;
  if (!w.SetCovariance(estimate.p)) return std::nullopt;
  return w;
}

}  // namespace mapmesh
