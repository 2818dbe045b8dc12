#include "common/slam/submap_joiner.h"

#include <gtest/gtest.h>

#include <set>

#include <Eigen/Cholesky>
#include <random>
#include <stdexcept>

#include "tests/testing/numeric_jacobian.h"

namespace mapmesh {
namespace {

TEST(PredictSubmap, JacobianMatchesCentralDifferences) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 5.0), a(-3.0, 3.0);
  for (int trial = 0; trial < 20; ++trial) {
    const int nl = trial % 4;
    Eigen::VectorXd x(6 + 2 * nl);
    for (int i = 0; i < x.size(); ++i) x(i) = (i == 2 || i == 5) ? a(rng) : u(rng);
    auto f = [nl](const Eigen::VectorXd& v) {
      std::vector<Eigen::Vector2d> l;
      for (int k = 0; k < nl; ++k) l.push_back(v.segment<2>(6 + 2 * k));
      return PredictSubmap({v(0), v(1), v(2)}, {v(3), v(4), v(5)}, l);
    };
    std::vector<Eigen::Vector2d> l;
    for (int k = 0; k < nl; ++k) l.push_back(x.segment<2>(6 + 2 * k));
    Eigen::MatrixXd j;
    PredictSubmap({x(0), x(1), x(2)}, {x(3), x(4), x(5)}, l, &j);
    const Eigen::MatrixXd num = testing::NumericJacobian(f, x, 1e-6, {2});
    EXPECT_LT((j - num).cwiseAbs().maxCoeff(), 1e-7) << "trial " << trial;
  }
}

TEST(PredictSubmap, IsTheEndPoseAndLandmarksInTheOriginFrame) {
  const Pose2 origin{1.0, 2.0, 0.5}, end{3.0, -1.0, 2.9};
  const Eigen::Vector2d l(4.0, 4.0);
  const Eigen::VectorXd h = PredictSubmap(origin, end, {l});
  const Pose2 rel = origin.Inverse() * end;
  EXPECT_NEAR(h(0), rel.x, 1e-12);
  EXPECT_NEAR(h(1), rel.y, 1e-12);
  EXPECT_NEAR(h(2), rel.theta, 1e-12);
  EXPECT_LT((h.segment<2>(3) - origin.Inverse().Apply(l)).norm(), 1e-12);
}

// The structured normal equations are the dense ones, J^T info J and J^T info e, at random
// states, information matrices and residuals.
TEST(SubmapNormalEquations, AreTheDenseProducts) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-5.0, 5.0), a(-3.0, 3.0);
  for (int trial = 0; trial < 30; ++trial) {
    const int nl = trial % 7;
    const int n = 3 + 2 * nl;
    std::vector<Eigen::Vector2d> l;
    for (int k = 0; k < nl; ++k) l.emplace_back(u(rng), u(rng));
    Eigen::MatrixXd j;
    PredictSubmap({u(rng), u(rng), a(rng)}, {u(rng), u(rng), a(rng)}, l, &j);
    Eigen::MatrixXd r(n, n);
    for (int i = 0; i < n * n; ++i) r(i) = u(rng);
    const Eigen::MatrixXd info = r * r.transpose() + Eigen::MatrixXd::Identity(n, n);
    Eigen::VectorXd e(n);
    for (int i = 0; i < n; ++i) e(i) = u(rng);
    Eigen::MatrixXd h;
    Eigen::VectorXd g;
    SubmapNormalEquations(j, info, e, &h, &g);
    const Eigen::MatrixXd h_dense = j.transpose() * info * j;
    const Eigen::VectorXd g_dense = j.transpose() * info * e;
    EXPECT_LT((h - h_dense).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + h_dense.cwiseAbs().maxCoeff())) << "trial " << trial;
    EXPECT_LT((g - g_dense).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + g_dense.cwiseAbs().maxCoeff())) << "trial " << trial;
  }
}

// A world and a chain of submap frames through it, and submaps measured from the truth with a
// correlated covariance (what an EKF's joint covariance looks like).
struct World {
  std::vector<Eigen::Vector2d> landmarks;
  std::vector<Pose2> frames;  // X_0 = identity, X_1, ...
};

World MakeWorld(std::mt19937_64& rng, int n_landmarks, int n_submaps, double step_m) {
  World w;
  std::uniform_real_distribution<double> u(-15.0, 15.0), turn(-0.6, 0.6);
  for (int i = 0; i < n_landmarks; ++i) w.landmarks.emplace_back(u(rng), u(rng));
  w.frames.push_back({});
  for (int k = 0; k < n_submaps; ++k) {
    Pose2 next = w.frames.back() * Pose2{step_m, 0.0, turn(rng)};
    // Stay in the world: turn back towards the middle when leaving it.
    if (std::hypot(next.x, next.y) > 12.0) next.theta = std::atan2(-next.y, -next.x);
    w.frames.push_back(next);
  }
  return w;
}

// Submap k of the world: the landmarks within range of X_k or X_k+1, measured with noise of
// covariance p (unless noise is off), keys = landmark indices.
SubmapEstimate Measure(const World& w, int k, double range, double sigma, std::mt19937_64& rng, bool noise = true) {
  SubmapEstimate s;
  std::vector<Eigen::Vector2d> seen;
  for (std::size_t i = 0; i < w.landmarks.size(); ++i) {
    const Eigen::Vector2d& l = w.landmarks[i];
    const auto near = [&](const Pose2& p) { return (l - Eigen::Vector2d(p.x, p.y)).norm() < range; };
    if (near(w.frames[k]) || near(w.frames[k + 1])) {
      s.keys.push_back(static_cast<std::uint32_t>(i));
      seen.push_back(l);
    }
  }
  const Eigen::VectorXd h = PredictSubmap(w.frames[k], w.frames[k + 1], seen);
  const Eigen::Index n = h.size();
  // Correlated: a shared frame error (the end pose's heading turns the landmarks) plus
  // independent parts.
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n + 3);
  a.leftCols(n).diagonal().setConstant(sigma);
  a(2, n) = sigma / 3.0;
  for (Eigen::Index r = 0; r < n; ++r) a(r, n + 1) = 0.5 * sigma;
  for (Eigen::Index r = 0; r < n; r += 2) a(r, n + 2) = 0.3 * sigma * ((r / 2) % 2 ? 1.0 : -1.0);
  s.p = a * a.transpose();
  s.x = h;
  if (noise) {
    Eigen::VectorXd e(n + 3);
    for (Eigen::Index i = 0; i < e.size(); ++i) e(i) = g(rng);
    s.x += a * e;
  }
  return s;
}

TEST(SubmapJoiner, OneSubmapIsItsOwnJoinedMap) {
  std::mt19937_64 rng(1);
  const World w = MakeWorld(rng, 20, 1, 3.0);
  const SubmapEstimate s = Measure(w, 0, 8.0, 0.05, rng);
  ASSERT_GE(s.keys.size(), 2u);
  SubmapJoiner j;
  j.Add(s);
  const JoinedMap m = j.last();
  ASSERT_EQ(m.keys.size(), s.keys.size());
  // With X_0 fixed, the least-squares estimate is the submap itself, covariance and all.
  for (std::size_t i = 0; i < s.keys.size(); ++i) {
    const std::size_t at = *m.Find(s.keys[i]);
    const auto row = static_cast<Eigen::Index>(3 + 2 * i);
    EXPECT_LT((m.means[at] - s.x.segment<2>(row)).norm(), 1e-9);
    EXPECT_LT((m.Cov(at) - s.p.block<2, 2>(row, row)).norm(), 1e-9 * s.p.norm());
  }
  EXPECT_LT((m.end_cov - s.p.topLeftCorner<3, 3>()).norm(), 1e-9 * s.p.norm());
  EXPECT_TRUE(m.converged);
}

TEST(SubmapJoiner, NoiselessSubmapsJoinToTheTruth) {
  for (int window : {1, 4, 1000}) {
    std::mt19937_64 rng(2);
    const World w = MakeWorld(rng, 60, 30, 2.5);
    SubmapJoiner j({.window = window});
    for (int k = 0; k < 30; ++k) j.Add(Measure(w, k, 7.0, 0.05, rng, false));
    const JoinedMap m = j.last();
    ASSERT_GT(m.keys.size(), 10u);
    for (std::size_t i = 0; i < m.keys.size(); ++i) {
      EXPECT_LT((m.means[i] - w.landmarks[m.keys[i]]).norm(), 1e-7) << "window " << window;
    }
    const Pose2& t = w.frames.back();
    EXPECT_LT(std::hypot(m.end.x - t.x, m.end.y - t.y), 1e-7);
    EXPECT_LT(std::abs(WrapAngle(m.end.theta - t.theta)), 1e-7);
  }
}

// Normalised estimation error squared of every joined landmark against the truth.
double MeanLandmarkNees(const JoinedMap& m, const World& w) {
  double sum = 0.0;
  for (std::size_t i = 0; i < m.keys.size(); ++i) {
    const Eigen::Vector2d e = m.means[i] - w.landmarks[m.keys[i]];
    sum += e.dot(m.Cov(i).ldlt().solve(e));
  }
  return sum / static_cast<double>(m.keys.size());
}

TEST(SubmapJoiner, JoinedMapIsConsistentOverSeededRuns) {
  // 40 runs of 25 submaps: the joined landmarks' mean NEES (2 dof) near 2, windowed or not.
  for (int window : {3, 1000}) {
    double nees = 0.0;
    const int runs = 40;
    for (int seed = 0; seed < runs; ++seed) {
      std::mt19937_64 rng(100 + seed);
      const World w = MakeWorld(rng, 50, 25, 2.0);
      SubmapJoiner j({.window = window});
      for (int k = 0; k < 25; ++k) j.Add(Measure(w, k, 7.0, 0.03, rng));
      nees += MeanLandmarkNees(j.last(), w);
    }
    nees /= runs;
    EXPECT_GT(nees, 1.6) << "window " << window;
    EXPECT_LT(nees, 2.4) << "window " << window;
  }
}

TEST(SubmapJoiner, WindowedJoiningMatchesTheFullSolveAndStaysBounded) {
  std::mt19937_64 rng(7);
  const World w = MakeWorld(rng, 40, 60, 2.0);
  SubmapJoiner windowed({.window = 5}), full({.window = 1000});
  for (int k = 0; k < 60; ++k) {
    const SubmapEstimate s = Measure(w, k, 7.0, 0.02, rng);
    windowed.Add(s);
    full.Add(s);
    EXPECT_LE(windowed.window_frames(), 6u);
    EXPECT_LE(windowed.prior_dim(), 2 * windowed.landmarks() + 3);
  }
  EXPECT_EQ(full.window_frames(), 60u);
  const JoinedMap a = windowed.last(), b = full.last();
  ASSERT_EQ(a.keys, b.keys);
  // Marginalised submaps keep the linearisation they left with: close to the full solution,
  // well inside the landmarks' uncertainty.
  for (std::size_t i = 0; i < a.keys.size(); ++i) {
    const double sigma = std::sqrt(b.Cov(i).trace());
    EXPECT_LT((a.means[i] - b.means[i]).norm(), 0.05 * sigma) << "landmark " << a.keys[i];
    EXPECT_LT((a.Cov(i) - b.Cov(i)).norm(), 0.05 * b.Cov(i).norm());
  }
}

TEST(SubmapJoiner, SolvingWithTheOpenSubmapLeavesTheJoinerUnchanged) {
  std::mt19937_64 rng(9);
  const World w = MakeWorld(rng, 40, 6, 2.0);
  SubmapJoiner j({.window = 2});
  for (int k = 0; k < 5; ++k) j.Add(Measure(w, k, 7.0, 0.02, rng));
  const SubmapEstimate open = Measure(w, 5, 7.0, 0.02, rng);
  const JoinedMap before = j.last();
  const JoinedMap with = j.Solve(&open);
  const JoinedMap again = j.Solve(&open);
  EXPECT_EQ(j.submaps(), 5u);
  EXPECT_EQ(with.means, again.means);
  // Without it, the solution of the last Add (marginalisation since then moves nothing): equal
  // to what the solver's stopping rule leaves, a step of JoinerOptions::tolerance.
  const double tol = 10.0 * JoinerOptions{}.tolerance;
  const JoinedMap without = j.Solve();
  ASSERT_EQ(without.keys, before.keys);
  for (std::size_t i = 0; i < before.keys.size(); ++i) EXPECT_LT((without.means[i] - before.means[i]).norm(), tol);
  // And it is what adding it gives.
  j.Add(open);
  ASSERT_EQ(j.last().keys, with.keys);
  for (std::size_t i = 0; i < with.keys.size(); ++i) EXPECT_LT((j.last().means[i] - with.means[i]).norm(), tol);
}

TEST(SubmapJoiner, RelinearisesWhatAnEkfCannot) {
  // Submap 0 ends after a blind turn: its end heading is 0.6 rad off, with a large variance.
  // Submap 1 maps the same landmarks precisely from that end pose. The first estimate of
  // X_1 is 0.6 rad wrong, far outside a linearisation's reach: Gauss-Newton iterates it away.
  World w;
  w.landmarks = {{3, 0}, {3, 3}, {0, 3}, {-2, 1}, {1, -2}};
  w.frames = {{}, {1.0, 0.5, 1.5}, {0.0, 1.0, -2.0}};
  std::mt19937_64 rng(0);
  SubmapEstimate s0 = Measure(w, 0, 100.0, 1e-3, rng, false), s1 = Measure(w, 1, 100.0, 1e-3, rng, false);
  for (SubmapEstimate* s : {&s0, &s1}) s->p = 1e-6 * Eigen::MatrixXd::Identity(s->x.size(), s->x.size());
  s0.x(2) += 0.6;
  s0.p(2, 2) = 0.25;
  SubmapJoiner j;
  j.Add(s0);
  j.Add(s1);
  const JoinedMap& m = j.last();
  EXPECT_TRUE(m.converged);
  EXPECT_GE(m.iterations, 3);
  for (std::size_t i = 0; i < 5; ++i) EXPECT_LT((m.means[i] - w.landmarks[m.keys[i]]).norm(), 1e-3);
  EXPECT_LT(std::abs(WrapAngle(m.end.theta - w.frames[2].theta)), 1e-3);
}

// The submap without the landmarks `drop` says nothing about (a Gaussian's marginal: its rows
// and columns left out).
SubmapEstimate Without(const SubmapEstimate& s, const std::set<std::uint32_t>& drop) {
  std::vector<Eigen::Index> rows{0, 1, 2};
  SubmapEstimate out;
  for (std::size_t j = 0; j < s.keys.size(); ++j) {
    if (drop.count(s.keys[j])) continue;
    out.keys.push_back(s.keys[j]);
    rows.push_back(3 + 2 * static_cast<Eigen::Index>(j));
    rows.push_back(4 + 2 * static_cast<Eigen::Index>(j));
  }
  out.x = s.x(rows);
  out.p = s.p(rows, rows);
  return out;
}

// Submap 3 ends after a blind turn: its end heading 0.5 rad off, with a variance that allows
// it. Submaps 4-6 map new ground only, so nothing corrects that heading before they leave a
// window of 2: the prior holds their landmarks linearised 0.5 rad wrong about X_4. From
// submap 7 on, old and new landmarks are seen together and the heading is found. With
// relinearise_m the joiner notices the estimate leaving the prior's linearisation point and
// ends at the full solve's answer; without it the map keeps a visible error.
TEST(SubmapJoiner, RelinearisesAPriorLinearisedAtAPoorEstimate) {
  std::mt19937_64 rng(11);
  const World w = MakeWorld(rng, 40, 30, 2.0);
  std::vector<SubmapEstimate> submaps;
  for (int k = 0; k < 30; ++k) submaps.push_back(Measure(w, k, 7.0, 0.02, rng));
  submaps[3].x(2) += 0.5;
  submaps[3].p(2, 2) += 0.25;
  std::set<std::uint32_t> old;
  for (int k = 0; k < 4; ++k) old.insert(submaps[k].keys.begin(), submaps[k].keys.end());
  for (int k = 4; k < 7; ++k) submaps[k] = Without(submaps[k], old);
  SubmapJoiner full({.window = 1000}), stale({.window = 2}), fluid({.window = 2, .relinearise_m = 0.1});
  for (const SubmapEstimate& s : submaps) {
    full.Add(s);
    stale.Add(s);
    fluid.Add(s);
    EXPECT_LE(fluid.window_frames(), 3u);
  }
  const JoinedMap &a = stale.last(), &b = fluid.last(), &c = full.last();
  ASSERT_EQ(a.keys, c.keys);
  ASSERT_EQ(b.keys, c.keys);
  double stale_gap = 0.0, fluid_gap = 0.0;
  for (std::size_t i = 0; i < c.keys.size(); ++i) {
    stale_gap = std::max(stale_gap, (a.means[i] - c.means[i]).norm());
    fluid_gap = std::max(fluid_gap, (b.means[i] - c.means[i]).norm());
  }
  EXPECT_GT(stale_gap, 0.1);   // the planted failure exists ...
  EXPECT_LT(fluid_gap, 0.01);  // ... and relinearising removes it
  EXPECT_GE(fluid.relinearisations(), 1);
  EXPECT_EQ(stale.relinearisations(), 0);
}

// On a run whose estimates never leave their linearisation point, nothing is relinearised and
// the result is the plain windowed join's.
TEST(SubmapJoiner, RelinearisingIsIdleWhenThePriorHolds) {
  std::mt19937_64 rng(7);
  const World w = MakeWorld(rng, 40, 60, 2.0);
  SubmapJoiner plain({.window = 5}), fluid({.window = 5, .relinearise_m = 0.1});
  for (int k = 0; k < 60; ++k) {
    const SubmapEstimate s = Measure(w, k, 7.0, 0.02, rng);
    plain.Add(s);
    fluid.Add(s);
  }
  EXPECT_EQ(fluid.relinearisations(), 0);
  EXPECT_EQ(fluid.last().means, plain.last().means);
}

TEST(SubmapJoiner, RefusesMalformedSubmaps) {
  SubmapJoiner j;
  SubmapEstimate s;
  s.x = Eigen::VectorXd::Zero(5);
  s.p = Eigen::MatrixXd::Identity(5, 5);
  s.keys = {1};
  j.Add(s);
  SubmapEstimate bad = s;
  bad.keys = {};
  EXPECT_THROW(j.Add(bad), std::invalid_argument);  // sizes
  bad = s;
  bad.x(3) = std::nan("");
  EXPECT_THROW(j.Add(bad), std::invalid_argument);
  bad = s;
  bad.p(0, 0) = -1.0;
  EXPECT_THROW(j.Add(bad), std::invalid_argument);  // not positive definite
  bad = s;
  bad.p(0, 1) = 0.5;
  EXPECT_THROW(j.Add(bad), std::invalid_argument);  // not symmetric
  bad.x = Eigen::VectorXd::Zero(7);
  bad.p = Eigen::MatrixXd::Identity(7, 7);
  bad.keys = {2, 2};
  EXPECT_THROW(j.Add(bad), std::invalid_argument);  // one landmark twice
  EXPECT_EQ(j.submaps(), 1u);
  EXPECT_THROW(SubmapJoiner({.window = 0}), std::invalid_argument);
}

}  // namespace
}  // namespace mapmesh
