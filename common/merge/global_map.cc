#include "common/merge/global_map.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "common/geometry/covariance2.h"
#include "common/merge/point_grid.h"
#include "common/slam/jcbb.h"
#include "common/solver/chi2.h"

namespace mapmesh {
namespace {

struct Cluster {
  Gaussian2 anchor;               // the estimate candidates are gated against
  std::vector<Gaussian2> inputs;  // everything fused into it, anchor first
  std::vector<LandmarkOrigin> origins;
  std::int32_t signature = -1;
};

// One gated candidate pairing of a source landmark with a cluster.
struct Edge {
  int s = 0;        // source landmark (index into the moved landmarks)
  int c = 0;        // cluster
  double d2 = 0.0;  // individual squared Mahalanobis distance
};

// Joint squared distance of pairings of source landmarks (group[item]) with clusters (target);
// the shared alignment error correlates the source landmarks. JCBB asks depth first, each
// hypothesis mostly the previous one plus a pairing: the Cholesky factor of the joint
// covariance and the whitened innovation are kept for the pairings asked last, and the prefix
// shared with them is extended by one 2-row block per pairing, O(n^2) each, instead of
// factoring the whole matrix anew, O(n^3).
class GroupJointD2 {
 public:
  GroupJointD2(const std::vector<Landmark>& moved, const std::vector<Eigen::Matrix<double, 2, 3>>& jac,
               const Eigen::Matrix3d& t_cov, const std::vector<Cluster>& clusters, const std::vector<int>& group)
      : moved_(moved), jac_(jac), t_cov_(t_cov), clusters_(clusters), group_(group) {
    const int rows = 2 * static_cast<int>(group.size());
    l_ = Eigen::MatrixXd::Zero(rows, rows);
    y_ = Eigen::VectorXd::Zero(rows);
  }

  double operator()(std::span<const JcbbPairing> pairs) {
    std::size_t keep = 0;
    while (keep < pairs.size() && keep < prefix_.size() && pairs[keep].item == prefix_[keep].item &&
           pairs[keep].target == prefix_[keep].target) {
      ++keep;
    }
    prefix_.resize(keep);
    d2_.resize(keep);
    for (std::size_t k = keep; k < pairs.size(); ++k) {
      prefix_.push_back(pairs[k]);
      d2_.push_back(Extend(static_cast<int>(k)));
    }
    return d2_.empty() ? 0.0 : d2_.back();
  }

 private:
  // Adds block row k (prefix_[k]) to the factor; returns the joint distance of pairings 0..k.
  double Extend(int k) {
    const double before = k == 0 ? 0.0 : d2_[k - 1];
    if (!std::isfinite(before)) return before;
    const int si = group_[prefix_[k].item];
    const Cluster& c = clusters_[prefix_[k].target];
    const int r = 2 * k;
    // The new block column of the joint covariance above the diagonal, whitened: l = L^-1 b.
    Eigen::Matrix<double, Eigen::Dynamic, 2> b(r, 2);
    const Eigen::Matrix<double, 2, 3> jp = jac_[si] * t_cov_;
    for (int a = 0; a < k; ++a) b.middleRows<2>(2 * a) = jac_[group_[prefix_[a].item]] * jp.transpose();
    const auto lower = l_.topLeftCorner(r, r).triangularView<Eigen::Lower>();
    if (r > 0) lower.solveInPlace(b);
    const Eigen::Matrix2d schur = c.anchor.cov + moved_[si].cov - b.transpose() * b;
    const Eigen::LLT<Eigen::Matrix2d> d(schur);
    if (d.info() != Eigen::Success || !(d.matrixLLT().diagonal().array() > 0.0).all())
      return std::numeric_limits<double>::infinity();
    l_.block(r, 0, 2, r) = b.transpose();
    l_.block<2, 2>(r, r) = d.matrixL();
    const Eigen::Vector2d nu = c.anchor.mean - moved_[si].mean;
    const Eigen::Vector2d rhs = r > 0 ? Eigen::Vector2d(nu - b.transpose() * y_.head(r)) : nu;
    const Eigen::Vector2d yk = d.matrixL().solve(rhs);
    y_.segment<2>(r) = yk;
    return before + yk.squaredNorm();
  }

  const std::vector<Landmark>& moved_;
  const std::vector<Eigen::Matrix<double, 2, 3>>& jac_;
  const Eigen::Matrix3d& t_cov_;
  const std::vector<Cluster>& clusters_;
  const std::vector<int>& group_;
  std::vector<JcbbPairing> prefix_;
  std::vector<double> d2_;  // joint distance of pairings 0..k
  Eigen::MatrixXd l_;       // lower Cholesky factor of the prefix's joint covariance
  Eigen::VectorXd y_;       // L^-1 nu
};

bool Usable(const Landmark& l, GlobalMapStats& stats) {
  switch (CheckEstimate({l.mean, l.cov})) {
    case FusionVerdict::kFused: return true;
    case FusionVerdict::kNonFiniteMean: ++stats.non_finite_mean; break;
    case FusionVerdict::kInvalidCovariance: ++stats.invalid_covariance; break;
    default: ++stats.singular_covariance; break;
  }
  ++stats.rejected_landmarks;
  return false;
}

bool ValidTransform(const MapSource& s) {
  if (!std::isfinite(s.to_own.x) || !std::isfinite(s.to_own.y) || !std::isfinite(s.to_own.theta)) return false;
  const Eigen::Matrix3d& c = s.to_own_cov;
  if (!c.allFinite() || (c - c.transpose()).norm() > 1e-9 * std::max(1e-300, c.norm())) return false;
  const double scale = std::max(1e-300, c.norm());
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(c).eigenvalues().minCoeff() >= -1e-12 * scale;
}

using Origin = std::array<std::uint32_t, 3>;  // robot, incarnation, landmark id

Origin OriginOf(const LandmarkOrigin& o) { return {o.robot, o.incarnation, o.id}; }

// An ambiguous group in canonical form: members ordered by origin, each with its candidate
// clusters ordered by their anchors' origins.
struct CanonicalGroup {
  AssociationMemo::Key key;
  std::vector<int> member;                 // canonical position -> index into the group
  std::vector<std::vector<int>> clusters;  // canonical position -> its candidate clusters, in key order
};

CanonicalGroup Canonical(const std::vector<int>& group, const std::vector<std::vector<Edge>>& edges_of,
                         const std::vector<Cluster>& clusters, const MapSource& src,
                         const std::vector<Landmark>& moved) {
  std::vector<std::pair<Origin, int>> members;
  for (std::size_t i = 0; i < group.size(); ++i) {
    members.push_back({Origin{src.robot, src.incarnation, moved[group[i]].id}, static_cast<int>(i)});
  }
  std::sort(members.begin(), members.end());
  CanonicalGroup g;
  for (const auto& [origin, i] : members) {
    std::vector<std::pair<Origin, int>> cands;
    for (const Edge& e : edges_of[group[i]]) cands.push_back({OriginOf(clusters[e.c].origins.front()), e.c});
    std::sort(cands.begin(), cands.end());
    g.key.insert(g.key.end(), origin.begin(), origin.end());
    g.key.push_back(static_cast<std::uint32_t>(cands.size()));
    g.member.push_back(i);
    g.clusters.emplace_back();
    for (const auto& [o, c] : cands) {
      g.key.insert(g.key.end(), o.begin(), o.end());
      g.clusters.back().push_back(c);
    }
  }
  return g;
}

}  // namespace

void AssociationMemo::BeginBuild() {
  stats_ = {};
  previous_ = std::move(current_);
  current_.clear();
}

const std::vector<int>* AssociationMemo::Previous(const Key& group) const {
  const auto it = previous_.find(group);
  return it == previous_.end() ? nullptr : &it->second;
}

void AssociationMemo::Keep(Key group, std::vector<int> choice, bool reused) {
  ++(reused ? stats_.reused : stats_.searched);
  current_.insert_or_assign(std::move(group), std::move(choice));
}

Landmark TransformLandmark(const Landmark& l, const Pose2& t, const Eigen::Matrix3d& t_cov) {
  return TransformLandmark(l, PoseMap2(t), t_cov, nullptr);
}

Landmark TransformLandmark(const Landmark& l, const PoseMap2& t, const Eigen::Matrix3d& t_cov,
                           Eigen::Matrix<double, 2, 3>* j_pose) {
  Landmark out = l;
  const Eigen::Matrix2d r = t.Rotation();
  Eigen::Matrix<double, 2, 3> j;
  out.mean = t.Apply(l.mean, &j);
  out.cov = r * l.cov * r.transpose() + j * t_cov * j.transpose();
  out.cov = 0.5 * (out.cov + out.cov.transpose()).eval();
  if (j_pose != nullptr) *j_pose = j;
  return out;
}

namespace {

// One source's gated candidates: a radius search on the clusters' anchors, then the Mahalanobis
// test. Per source landmark its edges (nearest first), per cluster the source landmarks gated to it.
struct Candidates {
  std::vector<std::vector<Edge>> edges_of;
  std::vector<std::vector<int>> sources_of;
};

Candidates GatedCandidates(const std::vector<Cluster>& clusters, const std::vector<Landmark>& moved, double gate) {
  Candidates out{std::vector<std::vector<Edge>>(moved.size()), std::vector<std::vector<int>>(clusters.size())};
  if (clusters.empty() || moved.empty()) return out;
  std::vector<Eigen::Vector2d> anchors;
  anchors.reserve(clusters.size());
  double max_anchor = 0.0;
  for (const Cluster& c : clusters) {
    anchors.push_back(c.anchor.mean);
    max_anchor = std::max(max_anchor, LargestEigenvalue(c.anchor.cov));
  }
  const PointGrid2 grid(anchors);
  for (std::size_t s = 0; s < moved.size(); ++s) {
    const double radius = std::sqrt(gate * (max_anchor + LargestEigenvalue(moved[s].cov)));
    grid.Visit(moved[s].mean, radius, [&](int c) {
      const Eigen::Vector2d nu = clusters[c].anchor.mean - moved[s].mean;
      const Eigen::Matrix2d cov = clusters[c].anchor.cov + moved[s].cov;
      const double d2 = nu.dot(cov.inverse() * nu);
      if (d2 < gate) {
        out.edges_of[s].push_back({static_cast<int>(s), c, d2});
        out.sources_of[c].push_back(static_cast<int>(s));
      }
      return false;
    });
    std::sort(out.edges_of[s].begin(), out.edges_of[s].end(),
              [](const Edge& a, const Edge& b) { return a.d2 != b.d2 ? a.d2 < b.d2 : a.c < b.c; });
  }
  return out;
}

// The source landmarks connected to s0 through shared candidate clusters (s0 first, the rest as
// found), each marked in group_of.
std::vector<int> ConnectedGroup(std::size_t s0, const Candidates& cand, std::vector<int>& group_of) {
  std::vector<int> group{static_cast<int>(s0)};
  group_of[s0] = static_cast<int>(s0);
  for (std::size_t h = 0; h < group.size(); ++h) {
    for (const Edge& e : cand.edges_of[group[h]]) {
      for (int s : cand.sources_of[e.c]) {
        if (group_of[s] < 0) {
          group_of[s] = static_cast<int>(s0);
          group.push_back(s);
        }
      }
    }
  }
  return group;
}

// The build's state across its sources: the clusters so far, the stats and the memo.
class GlobalMapBuild {
 public:
  GlobalMapBuild(const GlobalMapOptions& o, AssociationMemo* memo, GlobalMapStats& stats)
      : o_(o), memo_(memo), stats_(stats), gate_(Chi2Quantile(o.gate_probability, 2)) {}
  std::vector<Cluster>& clusters() { return clusters_; }
  void AddSource(const MapSource& src);

 private:
  void AssociateJointly(const MapSource& src, const std::vector<Landmark>& moved,
                        const std::vector<Eigen::Matrix<double, 2, 3>>& jac, const Candidates& cand,
                        const std::vector<int>& group, std::vector<int>& assign);
  void AssociateGreedily(const Candidates& cand, const std::vector<int>& group, std::vector<int>& assign) const;
  void Fuse(const MapSource& src, const std::vector<Landmark>& moved, const std::vector<int>& assign);

  const GlobalMapOptions& o_;
  AssociationMemo* memo_;
  GlobalMapStats& stats_;
  const double gate_;
  std::vector<double> joint_gate_{0.0};  // by pairings (from 1): the chi-squared quantile, 2 dof per pairing
  std::vector<Cluster> clusters_;
};

void GlobalMapBuild::AddSource(const MapSource& src) {
  if (!ValidTransform(src)) {
    ++stats_.rejected_sources;
    return;
  }
  ++stats_.sources;
  // The source's usable landmarks, in the own frame.
  std::vector<Landmark> moved;
  std::vector<Eigen::Matrix<double, 2, 3>> jac;
  const PoseMap2 to_own(src.to_own);
  for (const Landmark& l : src.map.landmarks) {
    if (!Usable(l, stats_)) continue;
    moved.push_back(TransformLandmark(l, to_own, src.to_own_cov, &jac.emplace_back()));
  }
  const Candidates cand = GatedCandidates(clusters_, moved, gate_);
  // Connected groups of source landmarks through shared candidate clusters: one candidate alone
  // is taken, an ambiguous group judged jointly (JCBB) or, beyond max_jcbb_landmarks, greedily.
  std::vector<int> assign(moved.size(), -1), group_of(moved.size(), -1);
  for (std::size_t s0 = 0; s0 < moved.size(); ++s0) {
    if (group_of[s0] >= 0 || cand.edges_of[s0].empty()) continue;
    std::vector<int> group = ConnectedGroup(s0, cand, group_of);
    if (group.size() == 1 && cand.edges_of[s0].size() == 1) {
      assign[s0] = cand.edges_of[s0][0].c;
      continue;
    }
    std::sort(group.begin(), group.end());
    if (static_cast<int>(group.size()) <= o_.max_jcbb_landmarks) {
      AssociateJointly(src, moved, jac, cand, group, assign);
    } else {
      AssociateGreedily(cand, group, assign);
    }
  }
  Fuse(src, moved, assign);
}

// An ambiguous group by joint compatibility; with a memo, the same members with the same
// candidates keep the earlier pairing while it is still jointly compatible.
void GlobalMapBuild::AssociateJointly(const MapSource& src, const std::vector<Landmark>& moved,
                                      const std::vector<Eigen::Matrix<double, 2, 3>>& jac, const Candidates& cand,
                                      const std::vector<int>& group, std::vector<int>& assign) {
  ++stats_.ambiguous_groups;
  GroupJointD2 incremental(moved, jac, src.to_own_cov, clusters_, group);
  const auto joint_d2 = [&](std::span<const JcbbPairing> pairs) { return incremental(pairs); };
  CanonicalGroup canonical;
  if (memo_ != nullptr) {
    canonical = Canonical(group, cand.edges_of, clusters_, src, moved);
    if (const std::vector<int>* kept = memo_->Previous(canonical.key)) {
      std::vector<JcbbPairing> pairs;
      for (std::size_t k = 0; k < kept->size(); ++k) {
        if ((*kept)[k] >= 0) pairs.push_back({canonical.member[k], 0, canonical.clusters[k][(*kept)[k]]});
      }
      std::sort(pairs.begin(), pairs.end(), [](const JcbbPairing& a, const JcbbPairing& b) { return a.item < b.item; });
      while (joint_gate_.size() <= pairs.size())
        joint_gate_.push_back(Chi2Quantile(o_.gate_probability, 2 * static_cast<int>(joint_gate_.size())));
      if (pairs.empty() || joint_d2(pairs) < joint_gate_[pairs.size()]) {
        for (const JcbbPairing& pr : pairs) assign[group[pr.item]] = pr.target;
        memo_->Keep(std::move(canonical.key), *kept, /*reused=*/true);
        return;
      }
    }
  }
  std::vector<std::vector<int>> candidates;
  for (int s : group) {
    candidates.emplace_back();
    for (const Edge& e : cand.edges_of[s]) candidates.back().push_back(e.c);
  }
  const JcbbResult best = JointCompatibility(candidates, joint_d2, o_.gate_probability, o_.max_jcbb_nodes);
  for (std::size_t i = 0; i < group.size(); ++i) {
    if (best.option[i] >= 0) assign[group[i]] = candidates[i][best.option[i]];
  }
  if (memo_ != nullptr) {
    std::vector<int> choice;
    for (std::size_t k = 0; k < canonical.member.size(); ++k) {
      const int chosen = assign[group[canonical.member[k]]];
      const auto& cands = canonical.clusters[k];
      const auto at = std::find(cands.begin(), cands.end(), chosen);
      choice.push_back(at == cands.end() ? -1 : static_cast<int>(at - cands.begin()));
    }
    memo_->Keep(std::move(canonical.key), std::move(choice), /*reused=*/false);
  }
}

// A group too large for joint compatibility: its pairings nearest first, each cluster once.
void GlobalMapBuild::AssociateGreedily(const Candidates& cand, const std::vector<int>& group,
                                       std::vector<int>& assign) const {
  ++stats_.greedy_groups;
  std::vector<Edge> all;
  for (int s : group) all.insert(all.end(), cand.edges_of[s].begin(), cand.edges_of[s].end());
  std::sort(all.begin(), all.end(), [](const Edge& a, const Edge& b) { return a.d2 < b.d2; });
  std::vector<bool> taken(clusters_.size(), false);
  for (const Edge& e : all) {
    if (assign[e.s] >= 0 || taken[e.c]) continue;
    assign[e.s] = e.c;
    taken[e.c] = true;
  }
}

// Fuses the source's landmarks into their matched clusters; starts new ones for the rest.
void GlobalMapBuild::Fuse(const MapSource& src, const std::vector<Landmark>& moved, const std::vector<int>& assign) {
  for (std::size_t s = 0; s < moved.size(); ++s) {
    const Gaussian2 e{moved[s].mean, moved[s].cov};
    const LandmarkOrigin origin{src.robot, src.incarnation, moved[s].id, src.relayed};
    if (assign[s] >= 0) {
      Cluster& c = clusters_[assign[s]];
      c.inputs.push_back(e);
      c.origins.push_back(origin);
      // A known identity survives inputs of unknown identity (peers' maps carry none);
      // two different known ones make it unknown.
      if (moved[s].signature >= 0 && c.signature != moved[s].signature) c.signature = -1;
      ++stats_.associated;
    } else {
      clusters_.push_back({e, {e}, {origin}, moved[s].signature});
      ++stats_.appended;
    }
  }
}

}  // namespace

GlobalMap BuildGlobalMap(const LandmarkMap& local, RobotId self, std::span<const MapSource> sources,
                         const GlobalMapOptions& o, std::uint32_t self_incarnation, AssociationMemo* memo) {
  GlobalMap g;
  if (memo != nullptr) memo->BeginBuild();
  GlobalMapBuild build(o, memo, g.stats);
  std::vector<Cluster>& clusters = build.clusters();
  clusters.reserve(local.size());
  for (const Landmark& l : local.landmarks) {
    if (!Usable(l, g.stats)) continue;
    const Gaussian2 e{l.mean, l.cov};
    clusters.push_back({e, {e}, {{self, self_incarnation, l.id}}, l.signature});
    ++g.stats.local;
  }
  for (const MapSource& src : sources) build.AddSource(src);

  g.map.landmarks.reserve(clusters.size());
  g.origins.reserve(clusters.size());
  for (Cluster& c : clusters) {
    const FusionResult f = mapmesh::Fuse(c.inputs, o.method);
    Landmark l;
    l.id = static_cast<std::uint32_t>(g.map.size());
    l.signature = c.signature;
    l.mean = f.ok() ? f.fused.mean : c.anchor.mean;
    l.cov = f.ok() ? f.fused.cov : c.anchor.cov;
    g.map.landmarks.push_back(l);
    g.origins.push_back(std::move(c.origins));
  }
  return g;
}

}  // namespace mapmesh
