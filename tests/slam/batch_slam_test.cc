#include "common/slam/batch_slam.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <random>
#include <set>

#include "common/geometry/rigid_fit.h"
#include "common/metrics/landmark_metrics.h"
#include "common/slam/ekf_slam.h"
#include "common/slam/observation_model.h"
#include "tests/testing/filter_noise.h"
#include "tests/testing/numeric_jacobian.h"

namespace mapmesh {
namespace {

using testing::NumericJacobian;
using testing::TestFilterNoise;

Pose2 PoseOf(const Eigen::VectorXd& v, int at) { return {v(at), v(at + 1), v(at + 2)}; }

// Both factors' Jacobians against central differences on seeded random poses, landmarks and
// measurements (headings and bearings anywhere on the circle, so wrapping is exercised).
TEST(BatchFactors, JacobiansMatchCentralDifferences) {
  std::mt19937_64 rng(23);
  std::uniform_real_distribution<double> u(-20, 20), a(-M_PI, M_PI);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::VectorXd x(6);
    x << u(rng), u(rng), a(rng), u(rng), u(rng), a(rng);
    const Pose2 delta{u(rng) / 10, u(rng) / 10, a(rng)};
    Eigen::Matrix3d ja, jb;
    RelativePoseError(PoseOf(x, 0), PoseOf(x, 3), delta, &ja, &jb);
    const Eigen::MatrixXd num = NumericJacobian(
        [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
          return RelativePoseError(PoseOf(v, 0), PoseOf(v, 3), delta);
        },
        x, 1e-6, {2});
    EXPECT_LT((ja - num.leftCols(3)).cwiseAbs().maxCoeff(), 1e-6) << trial;
    EXPECT_LT((jb - num.rightCols(3)).cwiseAbs().maxCoeff(), 1e-6) << trial;

    Eigen::VectorXd y(5);
    y << u(rng), u(rng), a(rng), u(rng), u(rng);
    const Eigen::Vector2d z(std::abs(u(rng)) + 0.5, a(rng));
    Eigen::Matrix<double, 2, 3> jp;
    Eigen::Matrix2d jm;
    RangeBearingError(PoseOf(y, 0), y.tail<2>(), z, &jp, &jm);
    const Eigen::MatrixXd num2 = NumericJacobian(
        [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return RangeBearingError(PoseOf(v, 0), v.tail<2>(), z); }, y,
        1e-6, {1});
    EXPECT_LT((jp - num2.leftCols(3)).cwiseAbs().maxCoeff(), 1e-6) << trial;
    EXPECT_LT((jm - num2.rightCols(2)).cwiseAbs().maxCoeff(), 1e-6) << trial;

    // The sighting: robot b's position from robot a.
    Eigen::Matrix<double, 2, 3> jsa, jsb;
    SightingError(PoseOf(x, 0), PoseOf(x, 3), z, &jsa, &jsb);
    const Eigen::MatrixXd num3 = NumericJacobian(
        [&](const Eigen::VectorXd& v) -> Eigen::VectorXd { return SightingError(PoseOf(v, 0), PoseOf(v, 3), z); }, x,
        1e-6, {1});
    EXPECT_LT((jsa - num3.leftCols(3)).cwiseAbs().maxCoeff(), 1e-6) << trial;
    EXPECT_LT((jsb - num3.rightCols(3)).cwiseAbs().maxCoeff(), 1e-6) << trial;
  }
  // At the truth both errors vanish, the bearing's wrapped.
  const Pose2 p{1, 2, 3.1};
  const Eigen::Vector2d m(-4, 2.05);
  EXPECT_LT(RangeBearingError(p, m, ObserveRangeBearing(p, m)).norm(), 1e-12);
  EXPECT_LT(RangeBearingError(p, m, ObserveRangeBearing(p, m) + Eigen::Vector2d(0, 2 * M_PI)).norm(), 1e-12);
  EXPECT_LT(RelativePoseError(p, Pose2{3, 1, -3.1}, Between(p, Pose2{3, 1, -3.1})).norm(), 1e-12);
}

// The builder integrates odometry as the EKF predicts it: the same motion, and the covariance
// the EKF's robot pose has after the same controls from a certain start.
TEST(BatchLogBuilder, IntegratesOdometryAsTheFilterPredicts) {
  const FilterNoise noise = TestFilterNoise();
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> v(0.0, 0.5), w(-0.6, 0.6), dt(0.02, 0.2);
  BatchLogBuilder builder(3, noise, 0.0, 10.0, Pose2{1, 2, 0.3});
  EkfSlam ekf(noise);
  Pose2 direct;
  for (int k = 0; k < 37; ++k) {
    const OdometryControl u{v(rng), w(rng), 0.0};
    const double d = dt(rng);
    builder.Move(u, d);
    ekf.Predict(u, d);
    direct = UnicycleMotion(direct, {u.v_mps, u.w_radps}, d);
  }
  // Observations: one kept; one without identity, one too far and one too near dropped; a
  // sighting of a robot ignored.
  std::vector<Observation> obs(5);
  obs[0] = {3.0, 0.1, 7, ObservationKind::kLandmark};
  obs[1] = {3.0, 0.1, -1, ObservationKind::kLandmark};
  obs[2] = {10.5, 0.1, 8, ObservationKind::kLandmark};
  obs[3] = {-0.1, 0.1, 9, ObservationKind::kLandmark};
  obs[4] = {2.0, 0.0, 2, ObservationKind::kRobot};
  builder.Scan(4.2, obs);
  const BatchRobotLog& log = builder.log();
  ASSERT_EQ(log.nodes.size(), 2u);
  EXPECT_EQ(log.robot, 3u);
  EXPECT_EQ(log.observations_dropped, 3);
  EXPECT_EQ(log.Observations(), 1u);
  const BatchNode& n = log.nodes[1];
  EXPECT_DOUBLE_EQ(n.stamp, 4.2);
  EXPECT_NEAR(n.delta.x, direct.x, 1e-12);
  EXPECT_NEAR(n.delta.y, direct.y, 1e-12);
  EXPECT_NEAR(WrapAngle(n.delta.theta - direct.theta), 0.0, 1e-12);
  EXPECT_NEAR(n.delta.x, ekf.robot().x, 1e-12);
  EXPECT_LT((n.delta_cov - ekf.robot_cov()).cwiseAbs().maxCoeff(), 1e-15);
  // A second scan with no odometry between is the same pose: it joins the node.
  builder.Scan(4.2, {obs[0]});
  EXPECT_EQ(builder.log().nodes.size(), 2u);
  EXPECT_EQ(builder.log().nodes[1].obs.size(), 2u);
  // A mark (a sighting's end) with no odometry since is that node too; after odometry, a node of
  // its own without observations, which a later scan without odometry between joins.
  EXPECT_EQ(builder.Mark(4.2), 1);
  builder.Move({0.3, 0.1, 0.0}, 0.1);
  EXPECT_EQ(builder.Mark(4.3), 2);
  EXPECT_TRUE(builder.log().nodes[2].obs.empty());
  EXPECT_DOUBLE_EQ(builder.log().nodes[2].stamp, 4.3);
  EXPECT_GT(builder.log().nodes[2].delta.x, 0.0);
  builder.Scan(4.3, {obs[0]});
  EXPECT_EQ(builder.log().nodes.size(), 3u);
  EXPECT_EQ(builder.log().nodes[2].obs.size(), 1u);
}

// A small world driven by the models themselves: robots on circles of their own among
// landmarks, odometry every 0.1 s and a scan every 0.5 s, with noise or without.
struct World {
  std::vector<Eigen::Vector2d> landmarks;
  std::vector<BatchRobotLog> logs;
  std::map<RobotId, std::map<double, Pose2>> truth;  // true pose at each scan stamp
  std::vector<BatchSighting> sightings;
};

// Beyond the defaults: the robots of the second half (by id) and a copy of the landmarks moved
// by `group_offset` in x (from 30 m apart the groups share nothing), and sightings of each other
// at every scan within the sensor's range (noise drawn from a generator of their own, so the
// other draws stay as without them).
struct WorldExtras {
  double group_offset = 0.0;
  bool sightings = false;
  bool landmarks = true;  // false: the second half's robots observe no landmark at all
};

World MakeWorld(std::uint64_t seed, int robots, bool noisy, bool starts_known, int steps = 600,
                const WorldExtras& extras = {}) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-12, 12);
  std::normal_distribution<double> n01;
  World w;
  for (int i = 0; i < 40; ++i) w.landmarks.emplace_back(u(rng), u(rng));
  if (extras.group_offset != 0.0) {
    for (int i = 0; i < 40; ++i)
      w.landmarks.push_back(w.landmarks[static_cast<std::size_t>(i)] + Eigen::Vector2d(extras.group_offset, 0.0));
  }
  std::map<RobotId, std::map<double, int>> node_at;
  const FilterNoise noise = TestFilterNoise();
  const double sv = std::sqrt(noise.control_cov(0, 0)), sw = std::sqrt(noise.control_cov(1, 1));
  const double sr = std::sqrt(noise.obs_cov(0, 0)), sb = std::sqrt(noise.obs_cov(1, 1));
  for (int r = 0; r < robots; ++r) {
    const RobotId id = static_cast<RobotId>(r + 1);
    Pose2 pose{u(rng) / 3, u(rng) / 3, WrapAngle(u(rng))};
    const bool second = 2 * r >= robots;
    if (second) pose.x += extras.group_offset;
    BatchLogBuilder b(id, noise, 0.0, 8.0, starts_known ? std::optional<Pose2>(pose) : std::nullopt);
    const UnicycleControl c{0.4, (r % 2 ? -1 : 1) * (0.08 + 0.03 * r)};
    double t = 0.0;
    for (int k = 1; k <= steps; ++k) {
      pose = UnicycleMotion(pose, c, 0.1);
      t = 0.1 * k;
      OdometryControl meas{c.v_mps, c.w_radps, 0.0};
      if (noisy) {
        meas.v_mps += sv * n01(rng);
        meas.w_radps += sw * n01(rng);
      }
      b.Move(meas, 0.1);
      if (k % 5 != 0) continue;
      std::vector<Observation> obs;
      for (std::size_t l = 0; l < w.landmarks.size(); ++l) {
        Eigen::Vector2d z = ObserveRangeBearing(pose, w.landmarks[l]);
        if (z(0) > 8.0 || std::abs(z(1)) > M_PI / 2) continue;
        if (noisy) z += Eigen::Vector2d(sr * n01(rng), sb * n01(rng));
        if (second && !extras.landmarks) continue;
        obs.push_back({z(0), z(1), static_cast<std::int32_t>(l), ObservationKind::kLandmark});
      }
      b.Scan(t, obs);
      if (extras.sightings) node_at[id][t] = b.Mark(t);
      w.truth[id][t] = pose;
    }
    w.logs.push_back(b.log());
  }
  if (extras.sightings) {
    std::mt19937_64 sight_rng(seed + 1000);
    for (const auto& [a, track] : w.truth) {
      for (const auto& [t, pose] : track) {
        for (const auto& [b, other] : w.truth) {
          if (a == b) continue;
          const Pose2& p = other.at(t);
          Eigen::Vector2d z = ObserveRangeBearing(pose, {p.x, p.y});
          if (z(0) > 8.0 || std::abs(z(1)) > M_PI / 2) continue;
          if (noisy) z += Eigen::Vector2d(sr * n01(sight_rng), sb * n01(sight_rng));
          w.sightings.push_back({a, node_at[a][t], b, node_at[b][t], t, z, TestFilterNoise().obs_cov});
        }
      }
    }
  }
  return w;
}

const CentralBatchOptions kFair{{}, StartKnowledge::kNone};
const CentralBatchOptions kKnownStarts{{}, StartKnowledge::kKnown};

std::vector<BatchSolution> Singles(const World& w) {
  std::vector<BatchSolution> out;
  for (const BatchRobotLog& log : w.logs) out.push_back(SolveSingleRobotBatch(log));
  return out;
}

double MaxError(const LandmarkMap& map, const std::vector<Eigen::Vector2d>& truth, const Pose2& frame = {}) {
  double e = 0.0;
  for (const Landmark& l : map.landmarks) e = std::max(e, (frame.Apply(l.mean) - truth[l.signature]).norm());
  return e;
}

// Noise-free streams: every batch solution is the truth.
TEST(Batch, NoiseFreeStreamsGiveTheTruth) {
  const World w = MakeWorld(1, 3, false, true);
  const std::vector<BatchSolution> singles = Singles(w);
  for (std::size_t r = 0; r < singles.size(); ++r) {
    EXPECT_TRUE(singles[r].report.converged) << singles[r].report.stop;
    EXPECT_GT(singles[r].map.size(), 5u);
    EXPECT_LT(MaxError(singles[r].map, w.landmarks), 1e-6) << "robot " << r + 1;
    EXPECT_GT(singles[r].solves, 1);  // started over growing prefixes
  }
  // With the starts known, and with only the gauge's (robot 1's, fixed at its true start): the
  // same truth.
  for (const CentralBatchOptions& options : {kKnownStarts, kFair}) {
    const BatchSolution central = SolveCentralBatch(w.logs, singles, {}, options);
    EXPECT_TRUE(central.report.converged);
    EXPECT_TRUE(central.covariance_ok);
    ASSERT_EQ(central.components.size(), 1u);
    EXPECT_TRUE(central.components[0].in_world);
    EXPECT_EQ(central.components[0].robots.front(), 1u);
    EXPECT_LT(MaxError(central.map, w.landmarks), 1e-6);
    for (const auto& [robot, track] : central.trajectories) {
      for (const BatchPose& p : track) {
        if (std::isnan(p.stamp)) continue;
        const Pose2 t = w.truth.at(robot).at(p.stamp);
        EXPECT_LT(std::hypot(p.pose.x - t.x, p.pose.y - t.y), 1e-6);
      }
    }
  }
  const BatchSolution central = SolveCentralBatch(w.logs, singles, {}, kFair);
  const BatchSolution known = SolveKnownPoseMap(w.logs, [&](RobotId r, double t) -> std::optional<Pose2> {
    return w.truth.at(r).at(t);
  });
  EXPECT_EQ(known.map.size(), central.map.size());
  EXPECT_LT(MaxError(known.map, w.landmarks), 1e-6);
}

// Unknown starts: the first robot's start is the frame, the others are found from the shared
// landmarks; the map is the truth in that frame.
TEST(Batch, UnknownStartsArePlacedByTheSharedLandmarks) {
  const World w = MakeWorld(2, 3, false, false);
  const std::vector<BatchSolution> singles = Singles(w);
  for (const CentralBatchOptions& options : {kKnownStarts, kFair}) {
    const BatchSolution central = SolveCentralBatch(w.logs, singles, {}, options);
    EXPECT_TRUE(central.report.converged);
    ASSERT_EQ(central.trajectories.size(), 3u);
    ASSERT_EQ(central.components.size(), 1u);
    EXPECT_FALSE(central.components[0].in_world);
    // The frame is robot 1's start: its true pose at t = 0, one odometry step before its first scan.
    const World known = MakeWorld(2, 3, false, true);
    const Pose2 frame = *known.logs[0].start;
    EXPECT_LT(MaxError(central.map, w.landmarks, frame), 1e-6);
  }
}

// Robots that share no landmark but see each other: the sightings tie their frames (one
// component), and noise-free they give the truth with only robot 1's start known. Without the
// sightings the two groups are components of their own, each solved and in its own gauge.
TEST(Batch, SightingsTieRobotsThatShareNoLandmark) {
  WorldExtras extras;
  extras.group_offset = 4.0;  // the groups' circles overlap: they see each other ...
  extras.sightings = true;
  extras.landmarks = false;  // ... but the second group maps no landmark
  const World w = MakeWorld(3, 4, false, true, 600, extras);
  ASSERT_FALSE(w.sightings.empty());
  const std::vector<BatchSolution> singles = Singles(w);
  const BatchSolution central = SolveCentralBatch(w.logs, singles, w.sightings, kFair);
  EXPECT_TRUE(central.report.converged) << central.report.stop;
  ASSERT_EQ(central.components.size(), 1u);
  EXPECT_EQ(central.components[0].robots.size(), 4u);
  EXPECT_EQ(central.sightings, w.sightings.size());
  EXPECT_EQ(central.sightings_left_out, 0u);
  EXPECT_LT(MaxError(central.map, w.landmarks), 1e-6);
  for (const auto& [robot, track] : central.trajectories) {
    for (const BatchPose& p : track) {
      if (std::isnan(p.stamp)) continue;
      const Pose2 t = w.truth.at(robot).at(p.stamp);
      EXPECT_LT(std::hypot(p.pose.x - t.x, p.pose.y - t.y), 1e-6) << "robot " << robot << " at " << p.stamp;
    }
  }
  // Without them robots 3 and 4 share nothing with anyone: components of their own.
  const BatchSolution apart = SolveCentralBatch(w.logs, singles, {}, kFair);
  ASSERT_EQ(apart.components.size(), 3u);
  EXPECT_EQ(apart.components[0].robots, (std::vector<RobotId>{1, 2}));
  EXPECT_EQ(apart.components[1].robots, (std::vector<RobotId>{3}));
  EXPECT_EQ(apart.components[2].robots, (std::vector<RobotId>{4}));
  EXPECT_EQ(apart.components[1].landmarks, 0);
}

// A window's exact estimate (the submap of its nodes): the whole log as one window is the
// single-robot optimum (the same landmarks, their marginals in the joint covariance), and
// noise-free every window holds the true end pose and landmarks in its first node's frame.
TEST(BatchWindow, IsTheWindowsOptimumInItsFirstNodesFrame) {
  const World w = MakeWorld(5, 1, true, false, 400);
  const BatchRobotLog& log = w.logs[0];
  const int n = static_cast<int>(log.nodes.size());
  const BatchSolution single = SolveSingleRobotBatch(log);
  const std::optional<WireSubmap> whole = SolveBatchWindow(log, 0, n - 1, true);
  ASSERT_TRUE(whole.has_value());
  ASSERT_EQ(whole->keys.size(), single.map.size());
  const Eigen::MatrixXd cov = whole->Covariance();
  for (std::size_t k = 0; k < whole->keys.size(); ++k) {
    const Landmark* l = single.map.Find(whole->keys[k]);
    ASSERT_NE(l, nullptr);
    const Eigen::Index at = 3 + 2 * static_cast<Eigen::Index>(k);
    EXPECT_LT((whole->x.segment<2>(at) - l->mean).norm(), 1e-6) << l->id;
    EXPECT_LT((cov.block<2, 2>(at, at) - l->cov).cwiseAbs().maxCoeff(), 1e-6 * l->cov.norm() + 1e-12) << l->id;
  }
  const Pose2& end = single.trajectories.at(log.robot).back().pose;
  EXPECT_LT(std::hypot(whole->x(0) - end.x, whole->x(1) - end.y), 1e-6);
  EXPECT_NEAR(whole->closed_s, log.nodes.back().stamp, 1e-12);

  const World clean = MakeWorld(5, 1, false, true, 400);
  const BatchRobotLog& c = clean.logs[0];
  const auto& truth = clean.truth.at(c.robot);
  for (int first = 1; first + 20 < static_cast<int>(c.nodes.size()); first += 20) {
    const std::optional<WireSubmap> s = SolveBatchWindow(c, first, first + 20, false);
    ASSERT_TRUE(s.has_value());
    const Pose2 origin = truth.at(c.nodes[static_cast<std::size_t>(first)].stamp);
    const Pose2 rel = Between(origin, truth.at(c.nodes[static_cast<std::size_t>(first + 20)].stamp));
    EXPECT_LT(std::hypot(s->x(0) - rel.x, s->x(1) - rel.y), 1e-6);
    EXPECT_LT(std::abs(WrapAngle(s->x(2) - rel.theta)), 1e-6);
    // Only the observations before the last node: the last node's are the next window's.
    std::set<std::uint32_t> seen;
    for (int i = first; i < first + 20; ++i) {
      for (const BatchObservation& o : c.nodes[static_cast<std::size_t>(i)].obs)
        seen.insert(static_cast<std::uint32_t>(o.landmark));
    }
    EXPECT_EQ(std::set<std::uint32_t>(s->keys.begin(), s->keys.end()), seen);
    for (std::size_t k = 0; k < s->keys.size(); ++k) {
      const Eigen::Vector2d t = origin.Inverse().Apply(clean.landmarks[s->keys[k]]);
      EXPECT_LT((s->x.segment<2>(3 + 2 * static_cast<Eigen::Index>(k)) - t).norm(), 1e-6);
    }
  }
}

// Two groups of robots far apart (no landmark, no sighting in common): each is a component,
// solved and scored on its own, none merged into the other; with noise, each is consistent in
// its own gauge (its first robot's true start).
TEST(Batch, DisconnectedGroupsAreSolvedAndScoredApart) {
  WorldExtras extras;
  extras.group_offset = 100.0;
  extras.sightings = true;  // out of range of each other: none across the groups
  const World clean = MakeWorld(4, 4, false, true, 600, extras);
  const BatchSolution exact = SolveCentralBatch(clean.logs, Singles(clean), clean.sightings, kFair);
  ASSERT_EQ(exact.components.size(), 2u);
  // The largest first: whichever group mapped more landmarks.
  EXPECT_GE(exact.components[0].landmarks, exact.components[1].landmarks);
  const int first = exact.components[0].robots.front() == 1 ? 0 : 1;
  EXPECT_EQ(exact.components[first].robots, (std::vector<RobotId>{1, 2}));
  EXPECT_EQ(exact.components[1 - first].robots, (std::vector<RobotId>{3, 4}));
  EXPECT_TRUE(exact.components[0].in_world && exact.components[1].in_world);
  EXPECT_LT(MaxError(exact.map, clean.landmarks), 1e-6);
  for (const Landmark& l : exact.map.landmarks) {
    EXPECT_EQ(exact.landmark_component.at(l.signature), l.signature < 40 ? first : 1 - first) << l.signature;
  }
  EXPECT_EQ(exact.observations_left_out, 0u);
  EXPECT_EQ(exact.sightings_left_out, 0u);
  double nees = 0.0;
  int n = 0;
  for (std::uint64_t seed = 40; seed < 50; ++seed) {
    const World w = MakeWorld(seed, 4, true, true, 400, extras);
    const BatchSolution s = SolveCentralBatch(w.logs, Singles(w), w.sightings, kFair);
    ASSERT_EQ(s.components.size(), 2u);
    ASSERT_TRUE(s.report.converged) << s.report.stop;
    // Scored by parts: a rigid fit of each component; one fit of both would be no worse here
    // (both are in the world frame), but a part left unfitted would leave its landmarks out.
    const MapQuality parts = EvaluateFittedParts(s.map, s.landmark_component, w.landmarks, {}, Pose2{});
    ASSERT_TRUE(parts.evaluated);
    EXPECT_EQ(parts.matched, static_cast<int>(s.map.size()));
    nees += EvaluateMap(s.map, w.landmarks, {}).nees_mean;
    ++n;
    // The components, moved apart by any rigid motion of one: the parts' score does not change.
    LandmarkMap moved = s.map;
    for (Landmark& l : moved.landmarks) {
      if (s.landmark_component.at(l.signature) == 1) l.mean = Pose2{5, -3, 0.4}.Apply(l.mean);
    }
    EXPECT_EQ(parts.truth_matched.size(), s.map.size());
    EXPECT_NEAR(EvaluateFittedParts(moved, s.landmark_component, w.landmarks, {}, Pose2{}).rmse_m, parts.rmse_m, 1e-9);
    EXPECT_GT(EvaluateFittedMap(moved, w.landmarks, {}, Pose2{}).rmse_m, 10 * parts.rmse_m);
  }
  EXPECT_GT(nees / n, 1.4);
  EXPECT_LT(nees / n, 2.7);
}

// With noise: the central map is consistent (its NEES near 2 over seeds) and better than each
// robot's own; the known-pose map is better still. The fair optimum (only robot 1's start) is
// consistent in robot 1's frame too, and no better than the known starts' after a rigid fit.
TEST(Batch, NoisyCentralMapIsConsistentAndBetween) {
  double nees = 0.0, fair_nees = 0.0;
  int n = 0, central_below_single = 0, pairs = 0, known_below_central = 0, known_starts_below_fair = 0;
  for (std::uint64_t seed = 10; seed < 30; ++seed) {
    const World w = MakeWorld(seed, 3, true, true, 400);
    const std::vector<BatchSolution> singles = Singles(w);
    const BatchSolution central = SolveCentralBatch(w.logs, singles, {}, kKnownStarts);
    ASSERT_TRUE(central.report.converged) << central.report.stop;
    EXPECT_NEAR(central.chi2_per_dof, 1.0, 0.15);
    const BatchSolution known = SolveKnownPoseMap(w.logs, [&](RobotId r, double t) -> std::optional<Pose2> {
      return w.truth.at(r).at(t);
    });
    const MapQuality c = EvaluateMap(central.map, w.landmarks, {});
    nees += c.nees_mean;
    const BatchSolution fair = SolveCentralBatch(w.logs, singles, {}, kFair);
    ASSERT_TRUE(fair.report.converged) << fair.report.stop;
    EXPECT_NEAR(fair.chi2_per_dof, 1.0, 0.15);
    EXPECT_LE(fair.report.final_cost, central.report.final_cost + 1e-9);  // fewer constraints
    fair_nees += EvaluateMap(fair.map, w.landmarks, {}).nees_mean;
    known_starts_below_fair += EvaluateFittedMap(central.map, w.landmarks, {}, Pose2{}).rmse_m <=
                               EvaluateFittedMap(fair.map, w.landmarks, {}, Pose2{}).rmse_m;
    ++n;
    known_below_central += EvaluateMap(known.map, w.landmarks, {}).rmse_m <= c.rmse_m;
    for (const BatchSolution& s : singles) {
      // The same landmarks: those the single robot mapped.
      LandmarkMap same;
      for (const Landmark& l : central.map.landmarks) {
        if (s.map.Find(static_cast<std::uint32_t>(l.signature))) same.landmarks.push_back(l);
      }
      ++pairs;
      central_below_single += EvaluateMap(same, w.landmarks, {}).rmse_m <= EvaluateMap(s.map, w.landmarks, {}).rmse_m;
    }
  }
  EXPECT_GT(nees / n, 1.5);
  EXPECT_LT(nees / n, 2.6);
  EXPECT_GT(fair_nees / n, 1.5);
  EXPECT_LT(fair_nees / n, 2.6);
  EXPECT_GE(known_starts_below_fair, n / 2);
  EXPECT_GE(known_below_central, 18);
  EXPECT_GE(central_below_single, pairs * 8 / 10);
}

}  // namespace
}  // namespace mapmesh
