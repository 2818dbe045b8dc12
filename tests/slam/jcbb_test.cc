#include "common/slam/jcbb.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <cmath>
#include <limits>
#include <random>

#include "common/solver/chi2.h"

namespace mapmesh {
namespace {

// A random problem with a true joint Mahalanobis distance: each (item, target) pairing has an
// innovation, and all innovations share a common error (like the robot pose or an alignment),
// so that pairings are correlated.
struct Problem {
  std::vector<std::vector<int>> candidates;
  std::vector<std::vector<Eigen::Vector2d>> nu;  // per item, per option
  double common = 0.3;                           // variance of the shared error, per axis

  double JointD2(std::span<const JcbbPairing> pairs) const {
    const int n = static_cast<int>(pairs.size());
    Eigen::VectorXd v(2 * n);
    Eigen::MatrixXd s = Eigen::MatrixXd::Constant(2 * n, 2 * n, 0.0);
    for (int a = 0; a < n; ++a) {
      v.segment<2>(2 * a) = nu[pairs[a].item][pairs[a].option];
      for (int b = 0; b < n; ++b) s.block<2, 2>(2 * a, 2 * b) = common * Eigen::Matrix2d::Identity();
      s.block<2, 2>(2 * a, 2 * a) += Eigen::Matrix2d::Identity();
    }
    return v.dot(s.llt().solve(v));
  }
};

Problem Random(std::mt19937_64& rng, int items, int targets) {
  Problem p;
  std::normal_distribution<double> g(0.0, 1.3);
  std::uniform_int_distribution<int> count(0, 3), target(0, targets - 1);
  for (int i = 0; i < items; ++i) {
    p.candidates.emplace_back();
    p.nu.emplace_back();
    for (int k = count(rng); k > 0; --k) {
      const int t = target(rng);
      if (std::find(p.candidates[i].begin(), p.candidates[i].end(), t) != p.candidates[i].end()) continue;
      p.candidates[i].push_back(t);
      p.nu[i].emplace_back(g(rng), g(rng));
    }
  }
  return p;
}

// Every assignment, by enumeration: valid when the targets are distinct and every prefix (in
// item order) passes the joint gate, as in the search. The best has the most pairings, then
// the lowest joint distance.
void BruteForce(const Problem& p, double prob, std::size_t k, std::vector<JcbbPairing>& cur, int& best_pairs,
                double& best_d2) {
  if (k == p.candidates.size()) {
    const double d2 = cur.empty() ? 0.0 : p.JointD2(cur);
    const int n = static_cast<int>(cur.size());
    if (n > best_pairs || (n == best_pairs && d2 < best_d2)) {
      best_pairs = n;
      best_d2 = d2;
    }
    return;
  }
  for (std::size_t o = 0; o < p.candidates[k].size(); ++o) {
    const int t = p.candidates[k][o];
    if (std::any_of(cur.begin(), cur.end(), [&](const JcbbPairing& q) { return q.target == t; })) continue;
    cur.push_back({static_cast<int>(k), static_cast<int>(o), t});
    if (p.JointD2(cur) < Chi2Quantile(prob, 2 * static_cast<int>(cur.size()))) {
      BruteForce(p, prob, k + 1, cur, best_pairs, best_d2);
    }
    cur.pop_back();
  }
  BruteForce(p, prob, k + 1, cur, best_pairs, best_d2);
}

TEST(Jcbb, FindsTheBestJointlyCompatibleHypothesisOnRandomProblems) {
  std::mt19937_64 rng(11);
  int nontrivial = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Problem p = Random(rng, 1 + trial % 7, 2 + trial % 5);
    const auto d2 = [&](std::span<const JcbbPairing> q) { return p.JointD2(q); };
    const JcbbResult r = JointCompatibility(p.candidates, d2, 0.95, 1000000);
    std::vector<JcbbPairing> cur;
    int want_pairs = 0;
    double want_d2 = std::numeric_limits<double>::infinity();
    BruteForce(p, 0.95, 0, cur, want_pairs, want_d2);
    ASSERT_FALSE(r.node_limit);
    EXPECT_EQ(r.pairings, want_pairs) << "trial " << trial;
    EXPECT_NEAR(r.joint_d2, want_pairs == 0 ? 0.0 : want_d2, 1e-9) << "trial " << trial;
    // The result is what it claims: distinct targets, and that joint distance.
    std::vector<JcbbPairing> chosen;
    for (std::size_t i = 0; i < r.option.size(); ++i) {
      if (r.option[i] < 0) continue;
      const int t = p.candidates[i][r.option[i]];
      for (const JcbbPairing& q : chosen) EXPECT_NE(q.target, t);
      chosen.push_back({static_cast<int>(i), r.option[i], t});
    }
    ASSERT_EQ(static_cast<int>(chosen.size()), r.pairings);
    if (!chosen.empty()) {
      EXPECT_NEAR(p.JointD2(chosen), r.joint_d2, 1e-9);
    }
    if (r.pairings >= 2) ++nontrivial;
  }
  EXPECT_GT(nontrivial, 50);  // the trials exercise joint hypotheses, not only single pairings
}

TEST(Jcbb, PrefersMorePairingsOverALowerDistance) {
  // Item 0 fits target 0 best, but then item 1 (whose only candidate is target 0) is left out.
  const std::vector<std::vector<int>> candidates = {{0, 1}, {0}};
  const auto d2 = [](std::span<const JcbbPairing> q) {
    double s = 0.0;
    for (const JcbbPairing& p : q) s += p.option == 0 && p.item == 0 ? 0.1 : 1.0;
    return s;
  };
  const JcbbResult r = JointCompatibility(candidates, d2, 0.95, 1000);
  EXPECT_EQ(r.pairings, 2);
  EXPECT_EQ(r.option, (std::vector<int>{1, 0}));
}

TEST(Jcbb, StopsAtTheNodeLimitWithTheBestSoFar) {
  // Depth first, the first leaf (every item paired with its first free target) is node 13.
  const std::vector<std::vector<int>> candidates(12, std::vector<int>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11});
  const auto d2 = [](std::span<const JcbbPairing> q) { return 0.01 * static_cast<double>(q.size()); };
  const JcbbResult early = JointCompatibility(candidates, d2, 0.95, 12);
  EXPECT_TRUE(early.node_limit);
  EXPECT_EQ(early.pairings, 0);
  EXPECT_EQ(early.option, std::vector<int>(12, -1));
  const JcbbResult later = JointCompatibility(candidates, d2, 0.95, 50);
  EXPECT_TRUE(later.node_limit);
  EXPECT_EQ(later.pairings, 12);
  for (int i = 0; i < 12; ++i) EXPECT_EQ(later.option[i], i);  // item i pairs with its first free target, i
}

}  // namespace
}  // namespace mapmesh
