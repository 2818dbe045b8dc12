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

GlobalMap BuildGlobalMap(const LandmarkMap& local, RobotId self, std::span<const MapSource> sources,
                         const GlobalMapOptions& o, std::uint32_t self_incarnation, AssociationMemo* memo) {
  GlobalMap g;
  if (memo != nullptr) memo->BeginBuild();
  std::vector<double> joint_gate{0.0};  // by pairings (from 1): the chi-squared quantile, 2 dof per pairing
  std::vector<Cluster> clusters;
  clusters.reserve(local.size());
  for (const Landmark& l : local.landmarks) {
    if (!Usable(l, g.stats)) continue;
    const Gaussian2 e{l.mean, l.cov};
    clusters.push_back({e, {e}, {{self, self_incarnation, l.id}}, l.signature});
    ++g.stats.local;
  }
  const double gate = Chi2Quantile(o.gate_probability, 2);

  for (const MapSource& src : sources) {
    if (!ValidTransform(src)) {
      ++g.stats.rejected_sources;
      continue;
    }
    ++g.stats.sources;
    // The source's usable landmarks, in the own frame.
    std::vector<Landmark> moved;
    std::vector<Eigen::Matrix<double, 2, 3>> jac;
    const PoseMap2 to_own(src.to_own);
    for (const Landmark& l : src.map.landmarks) {
      if (!Usable(l, g.stats)) continue;
      moved.push_back(TransformLandmark(l, to_own, src.to_own_cov, &jac.emplace_back()));
    }
    // Gated candidates: a radius search on the anchors, then the Mahalanobis test.
    std::vector<std::vector<Edge>> edges_of(moved.size());
    std::vector<std::vector<int>> sources_of(clusters.size());
    if (!clusters.empty() && !moved.empty()) {
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
            edges_of[s].push_back({static_cast<int>(s), c, d2});
            sources_of[c].push_back(static_cast<int>(s));
          }
          return false;
        });
        std::sort(edges_of[s].begin(), edges_of[s].end(),
                  [](const Edge& a, const Edge& b) { return a.d2 != b.d2 ? a.d2 < b.d2 : a.c < b.c; });
      }
    }
    // Connected groups of source landmarks through shared candidate clusters.
    std::vector<int> assign(moved.size(), -1), group_of(moved.size(), -1);
    for (std::size_t s0 = 0; s0 < moved.size(); ++s0) {
      if (group_of[s0] >= 0 || edges_of[s0].empty()) continue;
      std::vector<int> group{static_cast<int>(s0)};
      group_of[s0] = static_cast<int>(s0);
      for (std::size_t h = 0; h < group.size(); ++h) {
        for (const Edge& e : edges_of[group[h]]) {
          for (int s : sources_of[e.c]) {
            if (group_of[s] < 0) {
              group_of[s] = static_cast<int>(s0);
              group.push_back(s);
            }
          }
        }
      }
      if (group.size() == 1 && edges_of[s0].size() == 1) {
        assign[s0] = edges_of[s0][0].c;
        continue;
      }
      std::sort(group.begin(), group.end());
      if (static_cast<int>(group.size()) <= o.max_jcbb_landmarks) {
        ++g.stats.ambiguous_groups;
        GroupJointD2 incremental(moved, jac, src.to_own_cov, clusters, group);
        const auto joint_d2 = [&](std::span<const JcbbPairing> pairs) { return incremental(pairs); };
        CanonicalGroup canonical;
        if (memo != nullptr) {
          canonical = Canonical(group, edges_of, clusters, src, moved);
          if (const std::vector<int>* kept = memo->Previous(canonical.key)) {
            // The same members with the same candidates: the earlier pairing stands while it
            // is still jointly compatible.
            std::vector<JcbbPairing> pairs;
            for (std::size_t k = 0; k < kept->size(); ++k) {
              if ((*kept)[k] >= 0) pairs.push_back({canonical.member[k], 0, canonical.clusters[k][(*kept)[k]]});
            }
            std::sort(pairs.begin(), pairs.end(),
                      [](const JcbbPairing& a, const JcbbPairing& b) { return a.item < b.item; });
            while (joint_gate.size() <= pairs.size())
              joint_gate.push_back(Chi2Quantile(o.gate_probability, 2 * static_cast<int>(joint_gate.size())));
            if (pairs.empty() || joint_d2(pairs) < joint_gate[pairs.size()]) {
              for (const JcbbPairing& pr : pairs) assign[group[pr.item]] = pr.target;
              memo->Keep(std::move(canonical.key), *kept, /*reused=*/true);
              continue;
            }
          }
        }
        std::vector<std::vector<int>> candidates;
        for (int s : group) {
          candidates.emplace_back();
          for (const Edge& e : edges_of[s]) candidates.back().push_back(e.c);
        }
        const JcbbResult best = JointCompatibility(candidates, joint_d2, o.gate_probability, o.max_jcbb_nodes);
        for (std::size_t i = 0; i < group.size(); ++i) {
          if (best.option[i] >= 0) assign[group[i]] = candidates[i][best.option[i]];
        }
        if (memo != nullptr) {
          std::vector<int> choice;
          for (std::size_t k = 0; k < canonical.member.size(); ++k) {
            const int chosen = assign[group[canonical.member[k]]];
            const auto& cands = canonical.clusters[k];
            const auto at = std::find(cands.begin(), cands.end(), chosen);
            choice.push_back(at == cands.end() ? -1 : static_cast<int>(at - cands.begin()));
          }
          memo->Keep(std::move(canonical.key), std::move(choice), /*reused=*/false);
        }
      } else {
        ++g.stats.greedy_groups;
        std::vector<Edge> all;
        for (int s : group) all.insert(all.end(), edges_of[s].begin(), edges_of[s].end());
        std::sort(all.begin(), all.end(), [](const Edge& a, const Edge& b) { return a.d2 < b.d2; });
        std::vector<bool> taken(clusters.size(), false);
        for (const Edge& e : all) {
          if (assign[e.s] >= 0 || taken[e.c]) continue;
          assign[e.s] = e.c;
          taken[e.c] = true;
        }
      }
    }
    // Fuse into the matched clusters; start new ones for the rest.
    for (std::size_t s = 0; s < moved.size(); ++s) {
      const Gaussian2 e{moved[s].mean, moved[s].cov};
      const LandmarkOrigin origin{src.robot, src.incarnation, moved[s].id, src.relayed};
      if (assign[s] >= 0) {
        Cluster& c = clusters[assign[s]];
        c.inputs.push_back(e);
        c.origins.push_back(origin);
        // A known identity survives inputs of unknown identity (peers' maps carry none);
        // two different known ones make it unknown.
        if (moved[s].signature >= 0 && c.signature != moved[s].signature) c.signature = -1;
        ++g.stats.associated;
      } else {
        clusters.push_back({e, {e}, {origin}, moved[s].signature});
        ++g.stats.appended;
      }
    }
  }

  g.map.landmarks.reserve(clusters.size());
  g.origins.reserve(clusters.size());
  for (Cluster& c : clusters) {
    const FusionResult f = Fuse(c.inputs, o.method);
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
