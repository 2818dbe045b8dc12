#include "common/merge/fusion.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>

namespace mapmesh {
namespace {

// A random symmetric positive-definite n x n matrix with eigenvalues in [lo, hi].
Eigen::MatrixXd RandomSpd(int n, double lo, double hi, std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(lo, hi);
  Eigen::MatrixXd a(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) a(i, j) = g(rng);
  }
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(a);
  const Eigen::MatrixXd q = qr.householderQ();
  Eigen::VectorXd ev(n);
  for (int i = 0; i < n; ++i) ev(i) = u(rng);
  return q * ev.asDiagonal() * q.transpose();
}

Gaussian2 RandomEstimate(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 2.0);
  return {Eigen::Vector2d(g(rng), g(rng)), RandomSpd(2, 0.01, 1.0, rng)};
}

double MinEigen(const Eigen::Matrix2d& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(0.5 * (m + m.transpose())).eigenvalues().minCoeff();
}

// The fused error's true covariance when the inputs' errors have joint covariance p (2N x 2N):
// a fusion with information weights w_n I_n has error sum_n K_n e_n, K_n = cov_f w_n I_n.
Eigen::Matrix2d TrueFusedCov(const std::vector<Gaussian2>& in, const std::vector<double>& w, const Eigen::MatrixXd& p) {
  const int n = static_cast<int>(in.size());
  Eigen::Matrix2d total = Eigen::Matrix2d::Zero();
  for (int i = 0; i < n; ++i) total += w[i] * in[i].cov.inverse();
  const Eigen::Matrix2d cov_f = total.inverse();
  Eigen::MatrixXd k(2, 2 * n);
  for (int i = 0; i < n; ++i) k.block<2, 2>(0, 2 * i) = cov_f * w[i] * in[i].cov.inverse();
  return k * p * k.transpose();
}

TEST(Fusion, CovarianceIntersectionIsConsistentForAnyCorrelation) {
  // Inputs whose reported covariances are exactly their errors' marginals, correlated at
  // random (including strongly): every CI variant bounds the fused error's covariance.
  std::mt19937_64 rng(11);
  int info_overconfident = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const int n = 2 + trial % 3;
    const Eigen::MatrixXd p = RandomSpd(2 * n, 0.01, 1.0, rng);
    std::vector<Gaussian2> in(n);
    for (int i = 0; i < n; ++i) in[i] = {Eigen::Vector2d::Zero(), p.block<2, 2>(2 * i, 2 * i)};
    for (FusionMethod m : {FusionMethod::kCiConstant, FusionMethod::kCiDeterminant, FusionMethod::kCiTrace}) {
      const FusionResult r = Fuse(in, m);
      ASSERT_TRUE(r.ok());
      ASSERT_EQ(r.weights.size(), static_cast<std::size_t>(n));
      EXPECT_NEAR(std::accumulate(r.weights.begin(), r.weights.end(), 0.0), 1.0, 1e-12);
      for (double w : r.weights) EXPECT_GE(w, -1e-15);
      const Eigen::Matrix2d truth = TrueFusedCov(in, r.weights, p);
      EXPECT_GE(MinEigen(r.fused.cov - truth), -1e-10 * r.fused.cov.norm()) << ToString(m) << " trial " << trial;
    }
    const FusionResult info = Fuse(in, FusionMethod::kInformation);
    info_overconfident += MinEigen(info.fused.cov - TrueFusedCov(in, std::vector<double>(n, 1.0), p)) < -1e-9;
  }
  // The check can fail: information fusion, which assumes independence, is caught often.
  EXPECT_GT(info_overconfident, 200);
}

TEST(Fusion, InformationFusionEqualsAKalmanUpdateForIndependentInputs) {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    const Gaussian2 prior = RandomEstimate(rng), meas = RandomEstimate(rng);
    const Eigen::Matrix2d k = prior.cov * (prior.cov + meas.cov).inverse();
    const Eigen::Vector2d x = prior.mean + k * (meas.mean - prior.mean);
    const Eigen::Matrix2d pk = (Eigen::Matrix2d::Identity() - k) * prior.cov;
    const std::vector<Gaussian2> in{prior, meas};
    const FusionResult r = Fuse(in, FusionMethod::kInformation);
    ASSERT_TRUE(r.ok());
    EXPECT_LT((r.fused.mean - x).norm(), 1e-9 * (1.0 + x.norm()));
    EXPECT_LT((r.fused.cov - pk).norm(), 1e-9 * pk.norm());
  }
}

TEST(Fusion, ClosedFormWeightEqualsGoldenSectionSearch) {
  std::mt19937_64 rng(5);
  int interior = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Matrix2d a = RandomSpd(2, 0.01, 10.0, rng), b = RandomSpd(2, 0.01, 10.0, rng);
    for (CiCriterion c : {CiCriterion::kDeterminant, CiCriterion::kTrace}) {
      const double w = CiWeight(a, b, c), ws = CiWeightBySearch(a, b, c, 1e-10);
      EXPECT_NEAR(w, ws, 1e-6) << "trial " << trial;
      interior += w > 1e-6 && w < 1 - 1e-6;
    }
  }
  EXPECT_GT(interior, 500);  // about a quarter of the optima are interior: the stationary point is exercised
}

TEST(Fusion, TwoInputOptimumIsWhatFuseUses) {
  std::mt19937_64 rng(6);
  for (int trial = 0; trial < 200; ++trial) {
    const std::vector<Gaussian2> in{RandomEstimate(rng), RandomEstimate(rng)};
    const FusionResult r = Fuse(in, FusionMethod::kCiDeterminant);
    EXPECT_NEAR(r.weights[0], CiWeight(in[0].cov.inverse(), in[1].cov.inverse(), CiCriterion::kDeterminant), 1e-12);
    const FusionResult t = Fuse(in, FusionMethod::kCiTrace);
    EXPECT_NEAR(t.weights[0], CiWeight(in[0].cov.inverse(), in[1].cov.inverse(), CiCriterion::kTrace), 1e-12);
    // Optimal weights beat the constant ones on their own criterion.
    const FusionResult c = Fuse(in, FusionMethod::kCiConstant);
    EXPECT_LE(r.fused.cov.determinant(), c.fused.cov.determinant() * (1 + 1e-12));
    EXPECT_LE(t.fused.cov.trace(), c.fused.cov.trace() * (1 + 1e-12));
  }
}

TEST(Fusion, NWayOptimumBeatsEverySampledWeighting) {
  std::mt19937_64 rng(8);
  std::exponential_distribution<double> e(1.0);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<Gaussian2> in{RandomEstimate(rng), RandomEstimate(rng), RandomEstimate(rng), RandomEstimate(rng)};
    const double det = Fuse(in, FusionMethod::kCiDeterminant).fused.cov.determinant();
    const double tr = Fuse(in, FusionMethod::kCiTrace).fused.cov.trace();
    for (int s = 0; s < 2000; ++s) {
      std::vector<double> w(in.size());
      for (double& x : w) x = e(rng);  // uniform on the simplex after normalising
      const double sum = std::accumulate(w.begin(), w.end(), 0.0);
      Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
      for (std::size_t i = 0; i < in.size(); ++i) m += w[i] / sum * in[i].cov.inverse();
      const Eigen::Matrix2d c = m.inverse();
      ASSERT_LE(det, c.determinant() * (1 + 1e-9));
      ASSERT_LE(tr, c.trace() * (1 + 1e-9));
    }
  }
}

TEST(Fusion, EveryMethodIgnoresTheOrderOfItsInputs) {
  std::mt19937_64 rng(9);
  for (int trial = 0; trial < 100; ++trial) {
    std::vector<Gaussian2> in;
    for (int i = 0; i < 4; ++i) in.push_back(RandomEstimate(rng));
    for (FusionMethod m :
         {FusionMethod::kMaximumLikelihood, FusionMethod::kInformation, FusionMethod::kCiConstant,
          FusionMethod::kCiDeterminant, FusionMethod::kCiTrace, FusionMethod::kOgk, FusionMethod::kCiOgk}) {
      const FusionResult ref = Fuse(in, m);
      std::vector<Gaussian2> perm = in;
      std::shuffle(perm.begin(), perm.end(), rng);
      const FusionResult r = Fuse(perm, m);
      // Closed-form methods agree to rounding. The optimised CI weights are the argmin of a
      // function that is flat to second order there, so rounding moves them by about
      // sqrt(machine epsilon): their results agree to 1e-6, the tolerance of the weight itself.
      // OGK's medians do not depend on the order; its sums over the points agree to rounding.
      const bool optimised = m == FusionMethod::kCiDeterminant || m == FusionMethod::kCiTrace;
      const bool ogk = m == FusionMethod::kOgk || m == FusionMethod::kCiOgk;
      const double tol = optimised ? 1e-6 : ogk ? 1e-10 : 1e-12;
      EXPECT_LT((r.fused.mean - ref.fused.mean).norm(), tol * (1 + ref.fused.mean.norm())) << ToString(m);
      EXPECT_LT((r.fused.cov - ref.fused.cov).norm(), tol * ref.fused.cov.norm()) << ToString(m);
    }
  }
}

TEST(Fusion, MaximumLikelihoodIsTheSampleMeanAndCovariance) {
  const std::vector<Gaussian2> in{{{0.0, 0.0}, Eigen::Matrix2d::Identity()},
                                  {{2.0, 0.0}, 4 * Eigen::Matrix2d::Identity()}};
  const FusionResult r = Fuse(in, FusionMethod::kMaximumLikelihood);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.fused.mean.isApprox(Eigen::Vector2d(1.0, 0.0)));
  Eigen::Matrix2d expected;
  expected << 1.0, 0.0, 0.0, 0.0;  // eq. 79 with N = 2: rank one, whatever the inputs' covariances
  EXPECT_TRUE(r.fused.cov.isApprox(expected));
}

TEST(Fusion, EqualInputsKeepTheirCovarianceUnderCiAndHalveItUnderInformation) {
  const Eigen::Matrix2d c = (Eigen::Matrix2d() << 0.3, 0.1, 0.1, 0.2).finished();
  const std::vector<Gaussian2> in{{{1.0, 1.0}, c}, {{3.0, 1.0}, c}};
  for (FusionMethod m : {FusionMethod::kCiConstant, FusionMethod::kCiDeterminant, FusionMethod::kCiTrace}) {
    const FusionResult r = Fuse(in, m);
    EXPECT_TRUE(r.fused.cov.isApprox(c, 1e-12)) << ToString(m);
    EXPECT_TRUE(r.fused.mean.isApprox(Eigen::Vector2d(2.0, 1.0), 1e-12)) << ToString(m);
  }
  EXPECT_TRUE(Fuse(in, FusionMethod::kInformation).fused.cov.isApprox(0.5 * c, 1e-12));
}

TEST(Fusion, BadInputIsRejectedWithAReasonAndNothingIsFused) {
  const Gaussian2 good{{1.0, 2.0}, Eigen::Matrix2d::Identity()};
  Gaussian2 nan_mean = good;
  nan_mean.mean.x() = std::numeric_limits<double>::quiet_NaN();
  Gaussian2 inf_cov = good;
  inf_cov.cov(0, 0) = std::numeric_limits<double>::infinity();
  Gaussian2 not_psd = good;
  not_psd.cov << 1.0, 2.0, 2.0, 1.0;
  Gaussian2 asymmetric = good;
  asymmetric.cov << 1.0, 0.5, 0.0, 1.0;
  Gaussian2 singular = good;
  singular.cov << 1.0, 1.0, 1.0, 1.0;
  Gaussian2 zero = good;
  zero.cov.setZero();
  const std::vector<std::pair<Gaussian2, FusionVerdict>> cases{
      {nan_mean, FusionVerdict::kNonFiniteMean},      {inf_cov, FusionVerdict::kInvalidCovariance},
      {not_psd, FusionVerdict::kInvalidCovariance},   {asymmetric, FusionVerdict::kInvalidCovariance},
      {singular, FusionVerdict::kSingularCovariance}, {zero, FusionVerdict::kSingularCovariance}};
  for (FusionMethod m :
       {FusionMethod::kMaximumLikelihood, FusionMethod::kInformation, FusionMethod::kCiConstant,
        FusionMethod::kCiDeterminant, FusionMethod::kCiTrace, FusionMethod::kOgk, FusionMethod::kCiOgk}) {
    for (const auto& [bad, verdict] : cases) {
      const std::vector<Gaussian2> in{good, bad};
      const FusionResult r = Fuse(in, m);
      EXPECT_EQ(r.verdict, verdict) << ToString(m);
      EXPECT_EQ(r.bad_input, 1);
      EXPECT_FALSE(r.ok());
    }
    EXPECT_EQ(Fuse({}, m).verdict, FusionVerdict::kNoInputs);
    const std::vector<Gaussian2> one{good};
    const FusionResult single = Fuse(one, m);
    ASSERT_TRUE(single.ok());
    EXPECT_EQ(single.fused.mean, good.mean);
  }
}

TEST(Fusion, MethodNamesRoundTrip) {
  for (FusionMethod m : {FusionMethod::kMaximumLikelihood, FusionMethod::kInformation, FusionMethod::kCiConstant,
                         FusionMethod::kCiDeterminant, FusionMethod::kCiTrace, FusionMethod::kJoining,
                         FusionMethod::kOgk, FusionMethod::kCiOgk}) {
    EXPECT_EQ(ParseFusionMethod(ToString(m)), m);
  }
  EXPECT_EQ(ParseFusionMethod("ogk"), FusionMethod::kOgk);
  EXPECT_EQ(ParseFusionMethod("ci_ogk"), FusionMethod::kCiOgk);
  EXPECT_FALSE(ParseFusionMethod("kalman").has_value());
}

TEST(Fusion, PairFusionEqualsTheGeneralOne) {
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 200; ++trial) {
    const std::vector<Gaussian2> in{RandomEstimate(rng), RandomEstimate(rng)};
    for (FusionMethod m :
         {FusionMethod::kMaximumLikelihood, FusionMethod::kInformation, FusionMethod::kCiConstant,
          FusionMethod::kCiDeterminant, FusionMethod::kCiTrace, FusionMethod::kOgk, FusionMethod::kCiOgk}) {
      const FusionResult ref = Fuse(in, m);
      const std::optional<Gaussian2> pair = FusePair(in[0], in[1], m);
      ASSERT_TRUE(pair.has_value());
      EXPECT_LT((pair->mean - ref.fused.mean).norm(), 1e-9 * (1 + ref.fused.mean.norm())) << ToString(m);
      EXPECT_LT((pair->cov - ref.fused.cov).norm(), 1e-9 * (1 + ref.fused.cov.norm())) << ToString(m);
    }
  }
  Gaussian2 bad = RandomEstimate(rng);
  bad.cov << 1.0, 1.0, 1.0, 1.0;
  EXPECT_FALSE(FusePair(RandomEstimate(rng), bad, FusionMethod::kCiConstant).has_value());
}

TEST(FusionOgk, ThePatternHasTheMomentsOfTheStandardNormal) {
  const std::vector<Eigen::Vector2d>& q = OgkFusionPattern();
  ASSERT_EQ(q.size(), 256u);
  Eigen::Vector2d m = Eigen::Vector2d::Zero();
  Eigen::Matrix2d c = Eigen::Matrix2d::Zero();
  for (const auto& p : q) {
    m += p;
    c += p * p.transpose();
  }
  EXPECT_LT((m / 256.0).norm(), 1e-14);
  EXPECT_LT((c / 256.0 - Eigen::Matrix2d::Identity()).norm(), 1e-13);
}

TEST(FusionOgk, CopiesOfOneInputFuseToThatInputAtAnyOrientation) {
  // The calibration: the reweighting keeps whole rings of every copy, so the scatter is exactly
  // the input's covariance times the pattern's own factor, which the fusion divides out.
  std::mt19937_64 rng(31);
  for (int trial = 0; trial < 100; ++trial) {
    const Gaussian2 g = RandomEstimate(rng);
    const std::vector<Gaussian2> in(2 + trial % 3, g);
    for (FusionMethod m : {FusionMethod::kOgk, FusionMethod::kCiOgk}) {
      const FusionResult r = Fuse(in, m);
      ASSERT_TRUE(r.ok());
      EXPECT_LT((r.fused.mean - g.mean).norm(), 1e-9 * (1 + g.mean.norm())) << ToString(m);
      EXPECT_LT((r.fused.cov - g.cov).norm(), 1e-9 * g.cov.norm()) << ToString(m);
    }
  }
}

TEST(FusionOgk, OneOutlyingInputIsRejectedWhereCiFollowsIt) {
  // Three inputs agree (means within 0.3 of the origin, unit covariances); a fourth sits 20 away.
  const Eigen::Matrix2d i = Eigen::Matrix2d::Identity();
  const std::vector<Gaussian2> in{{{0.0, 0.0}, i}, {{0.3, 0.0}, i}, {{0.0, 0.3}, 0.5 * i}, {{20.0, 0.0}, i}};
  const FusionResult ogk = Fuse(in, FusionMethod::kOgk);
  const FusionResult ci = Fuse(in, FusionMethod::kCiConstant);
  ASSERT_TRUE(ogk.ok());
  EXPECT_LT(ogk.fused.mean.norm(), 0.35);  // within the agreeing inputs' spread
  EXPECT_GT(ci.fused.mean.x(), 4.0);       // CI moves a quarter of the way (its weight on the outlier)
  // The outlier's points are gone from the scatter: about the agreeing inputs' covariances,
  // not the 100 m^2 the outlier's spread would add along x.
  EXPECT_LT(ogk.fused.cov(0, 0), 1.5);
  EXPECT_GT(ogk.fused.cov(0, 0), 0.5);
  // Without the outlier OGK agrees with itself: the outlier changed the mean by little.
  const std::vector<Gaussian2> clean(in.begin(), in.begin() + 3);
  EXPECT_LT((Fuse(clean, FusionMethod::kOgk).fused.mean - ogk.fused.mean).norm(), 0.15);
}

TEST(FusionOgk, TheHybridKeepsTheSmallerEllipse) {
  const Eigen::Matrix2d i = Eigen::Matrix2d::Identity();
  // Two tight agreeing inputs and a very wide one: OGK rejects the wide one's points and keeps
  // the tight inputs' covariance, CI's equal weights give 1.5 times it. OGK is the smaller.
  const std::vector<Gaussian2> tight{{{0.0, 0.0}, i}, {{0.0, 0.0}, i}, {{0.0, 0.0}, 1e4 * i}};
  const FusionResult o = Fuse(tight, FusionMethod::kOgk), c = Fuse(tight, FusionMethod::kCiConstant);
  const FusionResult h = Fuse(tight, FusionMethod::kCiOgk);
  EXPECT_LT(o.fused.cov.determinant(), c.fused.cov.determinant());
  EXPECT_EQ(h.fused.cov, o.fused.cov);
  EXPECT_TRUE(h.weights.empty());
  // Random inputs: always the smaller of the two, CI's weights when CI is kept (here CI's
  // always: OGK's covariance is about the inputs' average, CI's below their harmonic mean).
  std::mt19937_64 rng(33);
  int ogk_kept = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<Gaussian2> in;
    for (int k = 0; k < 2 + trial % 3; ++k) in.push_back(RandomEstimate(rng));
    const FusionResult ro = Fuse(in, FusionMethod::kOgk), rc = Fuse(in, FusionMethod::kCiConstant);
    const FusionResult rh = Fuse(in, FusionMethod::kCiOgk);
    const bool ogk_smaller = ro.fused.cov.determinant() < rc.fused.cov.determinant();
    const FusionResult& expect = ogk_smaller ? ro : rc;
    EXPECT_EQ(rh.fused.mean, expect.fused.mean);
    EXPECT_EQ(rh.fused.cov, expect.fused.cov);
    EXPECT_EQ(rh.weights.size(), ogk_smaller ? 0u : in.size());
    ogk_kept += ogk_smaller;
  }
  std::printf("CI-OGK kept OGK in %d of 300 random cases\n", ogk_kept);
}

TEST(FusionOgk, ConsistencyByMonteCarloOverCorrelatedInputs) {
  // As the CI test above: inputs whose reported covariances are their errors' marginals,
  // correlated at random (joint covariance p); OGK is not linear in the inputs, so each case is
  // checked by drawing the errors (means e ~ N(0, p), truth 0) and averaging the fused NEES.
  // A consistent estimator's mean NEES is at most 2; with 60 draws its standard error is about
  // 0.26 at 2, so a case above 2.6 is overconfident. Information fusion is caught in some cases
  // (the check can fail); the measured figures are printed.
  std::mt19937_64 rng(41);
  std::normal_distribution<double> g(0.0, 1.0);
  const int cases = 100, draws = 60;
  double worst_ogk = 0.0, worst_hybrid = 0.0, sum_ogk = 0.0, sum_ci = 0.0, sum_hybrid = 0.0;
  int info_over = 0;
  for (int c = 0; c < cases; ++c) {
    const int n = 2 + c % 3;
    const Eigen::MatrixXd p = RandomSpd(2 * n, 0.01, 1.0, rng);
    const Eigen::MatrixXd l = p.llt().matrixL();
    double ne_ogk = 0.0, ne_ci = 0.0, ne_hybrid = 0.0, ne_info = 0.0;
    for (int d = 0; d < draws; ++d) {
      Eigen::VectorXd z(2 * n);
      for (int k = 0; k < 2 * n; ++k) z(k) = g(rng);
      const Eigen::VectorXd e = l * z;
      std::vector<Gaussian2> in(n);
      for (int i = 0; i < n; ++i) in[i] = {e.segment<2>(2 * i), p.block<2, 2>(2 * i, 2 * i)};
      const auto nees = [&](FusionMethod m) {
        const FusionResult r = Fuse(in, m);
        return r.fused.mean.dot(r.fused.cov.inverse() * r.fused.mean);
      };
      ne_ogk += nees(FusionMethod::kOgk);
      ne_ci += nees(FusionMethod::kCiConstant);
      ne_hybrid += nees(FusionMethod::kCiOgk);
      ne_info += nees(FusionMethod::kInformation);
    }
    ne_ogk /= draws;
    ne_ci /= draws;
    ne_hybrid /= draws;
    worst_ogk = std::max(worst_ogk, ne_ogk);
    worst_hybrid = std::max(worst_hybrid, ne_hybrid);
    sum_ogk += ne_ogk;
    sum_ci += ne_ci;
    sum_hybrid += ne_hybrid;
    info_over += ne_info / draws > 2.6;
    EXPECT_LT(ne_ogk, 2.6) << "case " << c;
    EXPECT_LT(ne_hybrid, 2.6) << "case " << c;
  }
  std::printf("mean NEES over %d cases: OGK %.3f (worst %.3f), CI %.3f, CI-OGK %.3f (worst %.3f); "
              "information above 2.6 in %d cases\n",
              cases, sum_ogk / cases, worst_ogk, sum_ci / cases, sum_hybrid / cases, worst_hybrid, info_over);
  EXPECT_GE(info_over, 5);
}

}  // namespace
}  // namespace mapmesh
