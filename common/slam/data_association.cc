#include "common/slam/data_association.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <limits>

#include "common/check.h"
#include "common/slam/jcbb.h"
#include "common/slam/observation_model.h"
#include "common/solver/chi2.h"

namespace mapmesh {
namespace {

// Innovation and measurement Jacobians of observation i against candidate j.
struct Pairing {
  int obs = 0, cand = 0;
  Eigen::Vector2d nu;
  Matrix23 hr;
  Eigen::Matrix2d hm;
  Eigen::MatrixXd hp;  // H P: 2 x (3 + 2K)
  double d2 = 0.0;
};

Pairing MakePairing(const AssociationProblem& p, int i, int j) {
  Pairing q;
  q.obs = i;
  q.cand = j;
  const Eigen::Vector2d zhat = ObserveRangeBearing(p.robot, p.means[j], &q.hr, &q.hm);
  q.nu = {p.z[i](0) - zhat(0), WrapAngle(p.z[i](1) - zhat(1))};
  const int c = 3 + 2 * j;
  q.hp = q.hr * p.joint_cov.topRows<3>() + q.hm * p.joint_cov.middleRows<2>(c);
  const Eigen::Matrix2d s = q.hp.leftCols<3>() * q.hr.transpose() + q.hp.middleCols<2>(c) * q.hm.transpose() +
                            p.obs_cov;
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(s);
  q.d2 = ldlt.info() == Eigen::Success ? q.nu.dot(ldlt.solve(q.nu)) : std::numeric_limits<double>::infinity();
  if (!std::isfinite(q.d2) || q.d2 < 0) q.d2 = std::numeric_limits<double>::infinity();
  return q;
}

// Joint Mahalanobis distance of a set of pairings (Neira & Tardos eq. 5-8).
double JointD2(const AssociationProblem& p, const std::vector<const Pairing*>& h) {
  const int k = static_cast<int>(h.size());
  Eigen::MatrixXd c(2 * k, 2 * k);
  Eigen::VectorXd nu(2 * k);
  for (int a = 0; a < k; ++a) {
    nu.segment<2>(2 * a) = h[a]->nu;
    for (int b = 0; b < k; ++b) {
      const int cb = 3 + 2 * h[b]->cand;
      c.block<2, 2>(2 * a, 2 * b) = h[a]->hp.leftCols<3>() * h[b]->hr.transpose() +
                                    h[a]->hp.middleCols<2>(cb) * h[b]->hm.transpose();
    }
    c.block<2, 2>(2 * a, 2 * a) += p.obs_cov;
  }
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(0.5 * (c + c.transpose()));
  if (ldlt.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return nu.dot(ldlt.solve(nu));
}

}  // namespace

AssociationProblem MakeAssociationProblem(const LandmarkFilter& filter, const Eigen::Matrix2d& obs_cov,
                                          const std::vector<Eigen::Vector2d>& z,
                                          const std::vector<std::int32_t>& signatures) {
  AssociationProblem p;
  p.robot = filter.robot();
  p.candidates = filter.Candidates();
  for (LandmarkId id : p.candidates) p.means.push_back(filter.Mean(id));
  p.joint_cov = filter.JointCov(p.candidates);
  p.obs_cov = obs_cov;
  p.z = z;
  p.signatures = signatures;
  return p;
}

double MahalanobisSquared(const AssociationProblem& problem, int i, int j, Eigen::Vector2d* innovation) {
  const Pairing q = MakePairing(problem, i, j);
  if (innovation) *innovation = q.nu;
  return q.d2;
}

AssociationResult Associate(const AssociationProblem& p, const AssociationOptions& options) {
  MAPMESH_CHECK(options.method != AssociationMethod::kAuto, "resolve association kAuto before associating");
  AssociationResult r;
  const int n = static_cast<int>(p.z.size()), k = static_cast<int>(p.candidates.size());
  r.match.assign(n, AssociationResult::kNew);
  const double gate = Chi2Quantile(options.gate_probability, 2);

  if (options.method == AssociationMethod::kKnown) {
    for (int i = 0; i < n; ++i) {
      if (p.signatures.size() <= static_cast<std::size_t>(i) || p.signatures[i] < 0) {
        r.match[i] = AssociationResult::kDiscard;
        ++r.unidentified;
        continue;
      }
      const auto it = std::find(p.candidates.begin(), p.candidates.end(), static_cast<LandmarkId>(p.signatures[i]));
      if (it == p.candidates.end()) continue;  // kNew: the caller checks the filter
      const int j = static_cast<int>(it - p.candidates.begin());
      if (MakePairing(p, i, j).d2 > gate) {
        r.match[i] = AssociationResult::kDiscard;
        ++r.rejected_by_gate;
      } else {
        r.match[i] = j;
      }
    }
    return r;
  }

  // Individual compatibility of every observation with every candidate.
  std::vector<std::vector<Pairing>> compatible(n);
  std::vector<double> nearest(n, std::numeric_limits<double>::infinity());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < k; ++j) {
      // Cheap Euclidean pre-filter on the predicted range.
      const double dr = std::abs((p.means[j] - Eigen::Vector2d(p.robot.x, p.robot.y)).norm() - p.z[i](0));
      if (dr > 50.0 * std::sqrt(p.obs_cov(0, 0)) + 10.0) continue;
      Pairing q = MakePairing(p, i, j);
      nearest[i] = std::min(nearest[i], q.d2);
      if (q.d2 < gate) compatible[i].push_back(std::move(q));
    }
    std::sort(compatible[i].begin(), compatible[i].end(),
              [](const Pairing& a, const Pairing& b) { return a.d2 < b.d2; });
  }

  std::vector<const Pairing*> chosen(n, nullptr);
  if (options.method == AssociationMethod::kIcnn) {
    // Nearest neighbour, each landmark taken at most once, closest pairs first.
    std::vector<const Pairing*> all;
    for (const auto& c : compatible) {
      for (const Pairing& q : c) all.push_back(&q);
    }
    std::sort(all.begin(), all.end(), [](const Pairing* a, const Pairing* b) { return a->d2 < b->d2; });
    std::vector<bool> used(k, false);
    for (const Pairing* q : all) {
      if (chosen[q->obs] || used[q->cand]) continue;
      chosen[q->obs] = q;
      used[q->cand] = true;
    }
  } else {
    std::vector<std::vector<int>> candidates(n);
    for (int i = 0; i < n; ++i) {
      for (const Pairing& q : compatible[i]) candidates[i].push_back(q.cand);
    }
    std::vector<const Pairing*> h;
    const JcbbResult jcbb = JointCompatibility(
        candidates,
        [&](std::span<const JcbbPairing> pairs) {
          h.clear();
          for (const JcbbPairing& q : pairs) h.push_back(&compatible[q.item][q.option]);
          return JointD2(p, h);
        },
        options.gate_probability, options.max_jcbb_nodes);
    for (int i = 0; i < n; ++i) {
      if (jcbb.option[i] >= 0) chosen[i] = &compatible[i][jcbb.option[i]];
    }
    r.jcbb_nodes = jcbb.nodes;
  }
  for (int i = 0; i < n; ++i) {
    if (chosen[i]) {
      r.match[i] = chosen[i]->cand;
    } else if (nearest[i] <= options.new_landmark_chi2) {
      r.match[i] = AssociationResult::kDiscard;
      ++r.ambiguous;
    }
  }
  return r;
}

}  // namespace mapmesh
