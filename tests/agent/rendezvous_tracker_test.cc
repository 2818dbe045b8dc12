#include "agent/rendezvous_tracker.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace mapmesh {
namespace {

constexpr double kSigmaRange = 0.05, kSigmaBearing = 0.01;
const Eigen::Matrix3d kCov = Eigen::Vector3d(1e-4, 1e-4, 1e-6).asDiagonal();

// Robot 1's map frame is the world's; robot 2's frame sits at kFrame2 in it.
const Pose2 kFrame2{12.0, -4.0, 0.9};

// The robots' true paths: two arcs that pass each other.
Pose2 Truth(RobotId r, double t) {
  if (r == 1) return {t * 0.5, 2.0 * std::sin(0.1 * t), 0.1 * std::cos(0.1 * t)};
  return {10.0 - t * 0.3, 3.0 + std::cos(0.07 * t), M_PI - 0.05 * t};
}
// The pose estimate in the robot's own frame (exact: the cases below are about the protocol).
Pose2 Estimate(RobotId r, double t) { return r == 1 ? Truth(1, t) : kFrame2.Inverse() * Truth(2, t); }

// A reading of robot `seen` from robot `by` at t.
Observation Sees(RobotId by, RobotId seen, double t) {
  const Eigen::Vector2d rel = Truth(by, t).Inverse().Apply(Eigen::Vector2d(Truth(seen, t).x, Truth(seen, t).y));
  Observation o;
  o.range = rel.norm();
  o.bearing = std::atan2(rel.y(), rel.x());
  o.signature = static_cast<std::int32_t>(seen);
  o.kind = ObservationKind::kRobot;
  return o;
}

RendezvousTracker Tracker(RobotId self, std::uint32_t incarnation = 1, RendezvousOptions o = {}) {
  return RendezvousTracker(self, incarnation, {1, 2, 3}, o, kSigmaRange, kSigmaBearing);
}

// Robots 1 and 2 move in 0.5 s steps up to `until`, each seeing the other every step when
// `mutual`, else only robot 2 seeing robot 1; their messages are delivered at once.
void Drive(RendezvousTracker& a, RendezvousTracker& b, double until, bool mutual) {
  for (double t = 0.5; t <= until + 1e-9; t += 0.5) {
    std::vector<Sighting> out;
    for (RobotId r : {1u, 2u}) {
      RendezvousTracker& me = r == 1 ? a : b;
      me.OnPose(t, Estimate(r, t), kCov);
      if (r == 1 && !mutual) continue;
      for (Sighting& m : me.OnScan({Sees(r, 3 - r, t)}, t, Estimate(r, t), kCov)) out.push_back(m);
    }
    for (Sighting& m : a.Advance(t)) out.push_back(m);
    for (Sighting& m : b.Advance(t)) out.push_back(m);
    for (const Sighting& m : out) {
      a.OnMessage(m);
      b.OnMessage(m);
    }
  }
}

TEST(RendezvousTrackerTest, SightingsOfAPeerArePublishedAtMostOncePerPeriod) {
  RendezvousOptions o;
  o.period_s = 1.0;
  RendezvousTracker a = Tracker(1, 1, o);
  int sent = 0;
  for (double t = 0.25; t <= 10.0 + 1e-9; t += 0.25) {
    const auto out = a.OnScan({Sees(1, 2, t)}, t, Estimate(1, t), kCov);
    for (const Sighting& m : out) {
      EXPECT_EQ(m.kind, SightingKind::kSighting);
      EXPECT_EQ(m.other, 2u);
      EXPECT_NEAR(m.range, Sees(1, 2, t).range, 1e-12);
    }
    sent += static_cast<int>(out.size());
  }
  EXPECT_EQ(sent, 10);
  EXPECT_EQ(a.stats().sightings_sent, 10u);
  // Robots outside the run, itself, landmarks and unknown identities are no sightings.
  Observation outside = Sees(1, 2, 11.0), landmark = outside, unknown = outside;
  outside.signature = 9;
  landmark.kind = ObservationKind::kLandmark;
  unknown.signature = -1;
  EXPECT_TRUE(a.OnScan({outside, landmark, unknown}, 20.0, Estimate(1, 20.0), kCov).empty());
}

TEST(RendezvousTrackerTest, MutualSightingsAndAnswersRecoverThePeersFrame) {
  RendezvousTracker a = Tracker(1), b = Tracker(2);
  Drive(a, b, 8.0, true);
  EXPECT_GT(a.stats().answers_used, 0u);    // robot 2 answered robot 1's sightings
  EXPECT_GT(a.stats().sightings_used, 0u);  // robot 1 answered robot 2's
  EXPECT_GT(a.stats().mutual, 0u);
  const auto fits = a.TakeFits();
  ASSERT_EQ(fits.size(), 1u);
  EXPECT_EQ(fits[0].first, (PeerKey{2, 1}));
  const RendezvousFit& fit = fits[0].second;
  ASSERT_TRUE(fit.accepted()) << static_cast<int>(fit.verdict);
  EXPECT_NEAR(fit.transform.x, kFrame2.x, 1e-6);
  EXPECT_NEAR(fit.transform.y, kFrame2.y, 1e-6);
  EXPECT_NEAR(WrapAngle(fit.transform.theta - kFrame2.theta), 0.0, 1e-6);
  // Robot 2 finds robot 1's frame in its own: the inverse.
  const auto back = b.TakeFits();
  ASSERT_EQ(back.size(), 1u);
  ASSERT_TRUE(back[0].second.accepted());
  EXPECT_NEAR(back[0].second.transform.x, kFrame2.Inverse().x, 1e-6);
  // A fit is given again only after new correspondences arrived.
  EXPECT_TRUE(a.TakeFits().empty());
}

TEST(RendezvousTrackerTest, OneWaySightingsGiveAFitFromPointsAlone) {
  RendezvousTracker a = Tracker(1), b = Tracker(2);
  Drive(a, b, 10.0, false);
  EXPECT_EQ(a.stats().mutual, 0u);
  EXPECT_EQ(a.stats().sightings_sent, 0u);
  const auto fits = a.TakeFits();
  ASSERT_EQ(fits.size(), 1u);
  EXPECT_EQ(fits[0].second.mutual, 0);
  ASSERT_TRUE(fits[0].second.accepted()) << static_cast<int>(fits[0].second.verdict);
  EXPECT_NEAR(fits[0].second.transform.x, kFrame2.x, 1e-6);
}

TEST(RendezvousTrackerTest, APeersSightingWaitsUntilOurPoseAtItsStampIsKnown) {
  RendezvousTracker a = Tracker(1), b = Tracker(2);
  b.OnPose(5.0, Estimate(2, 5.0), kCov);
  const auto sightings = b.OnScan({Sees(2, 1, 5.0)}, 5.0, Estimate(2, 5.0), kCov);
  ASSERT_EQ(sightings.size(), 1u);
  a.OnMessage(sightings[0]);
  a.OnPose(4.5, Estimate(1, 4.5), kCov);
  EXPECT_TRUE(a.Advance(4.5).empty());  // robot 1 has not reached 5 s yet
  a.OnPose(5.5, Estimate(1, 5.5), kCov);
  const auto answers = a.Advance(5.5);  // its pose at 5 s, interpolated between 4.5 s and 5.5 s
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].kind, SightingKind::kAnswer);
  EXPECT_EQ(answers[0].other, 2u);
  EXPECT_DOUBLE_EQ(answers[0].stamp, 5.0);
  EXPECT_NEAR(answers[0].x, Interpolate(Estimate(1, 4.5), Estimate(1, 5.5), 0.5).x, 1e-12);
  // Poses further apart than max_pose_gap_s give no pose between them.
  RendezvousTracker c = Tracker(3);
  c.OnMessage([&] {
    Sighting m = sightings[0];
    m.other = 3;
    return m;
  }());
  c.OnPose(4.0, Estimate(1, 4.0), kCov);
  c.OnPose(6.0, Estimate(1, 6.0), kCov);
  EXPECT_TRUE(c.Advance(6.0).empty());
  EXPECT_EQ(c.stats().unmatched, 1u);
  EXPECT_EQ(a.stats().sightings_used, 1u);
}

TEST(RendezvousTrackerTest, MalformedForeignAndUnmatchedMessagesAreCountedOrIgnored) {
  RendezvousTracker a = Tracker(1), b = Tracker(2);
  b.OnPose(1.0, Estimate(2, 1.0), kCov);
  const Sighting good = b.OnScan({Sees(2, 1, 1.0)}, 1.0, Estimate(2, 1.0), kCov).at(0);
  Sighting nan = good, bad_cov = good, negative = good;
  nan.x = std::nan("");
  bad_cov.cov = {1.0, 2.0, 0.0, 1.0, 0.0, 1.0};  // not positive-definite
  negative.range = -1.0;
  for (const Sighting& m : {nan, bad_cov, negative}) {
    EXPECT_FALSE(SightingWellFormed(m));
    a.OnMessage(m);
  }
  EXPECT_EQ(a.stats().refused, 3u);
  Sighting other = good, outsider = good;
  other.other = 3;        // about another robot
  outsider.robot_id = 9;  // from a robot outside the run
  a.OnMessage(other);
  a.OnMessage(outsider);
  a.OnPose(1.0, Estimate(1, 1.0), kCov);
  EXPECT_TRUE(a.Advance(1.0).empty());
  EXPECT_EQ(a.stats().refused, 3u);
  // An answer to a sighting we never made.
  Sighting answer = good;
  answer.kind = SightingKind::kAnswer;
  answer.other_incarnation = 1;
  a.OnMessage(answer);
  EXPECT_EQ(a.stats().unmatched, 1u);
  // ... and one to an earlier incarnation of ours is not ours to use.
  answer.other_incarnation = 7;
  a.OnMessage(answer);
  EXPECT_EQ(a.stats().unmatched, 1u);
  EXPECT_EQ(a.stats().answers_used, 0u);
}

TEST(RendezvousTrackerTest, SightingsOlderThanThePoseWindowFindNothing) {
  RendezvousOptions o;
  o.window_s = 10.0;
  RendezvousTracker a = Tracker(1, 1, o), b = Tracker(2);
  for (double t = 0.0; t <= 30.0 + 1e-9; t += 0.5) a.OnPose(t, Estimate(1, t), kCov);
  b.OnPose(5.0, Estimate(2, 5.0), kCov);
  a.OnMessage(b.OnScan({Sees(2, 1, 5.0)}, 5.0, Estimate(2, 5.0), kCov).at(0));
  EXPECT_TRUE(a.Advance(30.0).empty());
  EXPECT_EQ(a.stats().unmatched, 1u);
}

TEST(RendezvousTrackerTest, PeerFramesAndPendingSightingsAreBounded) {
  RendezvousOptions o;
  o.max_frames_per_robot = 3;
  o.max_pending = 4;
  RendezvousTracker a = Tracker(1, 1, o);
  // Sightings of robot 1 from six incarnations of robot 2, one a second, each answered: the
  // three frames updated last are kept.
  double t = 0.0;
  for (std::uint32_t inc = 1; inc <= 6; ++inc) {
    for (; t <= inc + 1e-9; t += 0.5) a.OnPose(t, Estimate(1, t), kCov);
    RendezvousTracker b = Tracker(2, inc);
    b.OnPose(inc, Estimate(2, inc), kCov);
    a.OnMessage(b.OnScan({Sees(2, 1, inc)}, inc, Estimate(2, inc), kCov).at(0));
    EXPECT_EQ(a.Advance(inc).size(), 1u);
  }
  const auto fits = a.TakeFits();
  ASSERT_EQ(fits.size(), 3u);
  EXPECT_EQ(fits[0].first, (PeerKey{2, 4}));
  // Ten sightings far ahead of us: the oldest beyond max_pending are dropped unanswered.
  RendezvousTracker b = Tracker(2, 9);
  for (int i = 0; i < 10; ++i) {
    const double t = 30.0 + i;
    b.OnPose(t, Estimate(2, t), kCov);
    a.OnMessage(b.OnScan({Sees(2, 1, t)}, t, Estimate(2, t), kCov).at(0));
  }
  for (; t <= 40.0 + 1e-9; t += 0.5) a.OnPose(t, Estimate(1, t), kCov);
  EXPECT_EQ(a.Advance(40.0).size(), 4u);
}

}  // namespace
}  // namespace mapmesh
