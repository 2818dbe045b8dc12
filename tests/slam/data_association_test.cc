#include "common/slam/data_association.h"

#include <gtest/gtest.h>

#include "common/slam/observation_model.h"

namespace mapmesh {
namespace {

// Two landmarks 1 m apart, 5 m ahead; the robot's y is very uncertain.
AssociationProblem TwoLandmarks() {
  AssociationProblem p;
  p.robot = {0, 0, 0};
  p.candidates = {10, 11};
  p.means = {{5, 0}, {5, 1}};
  p.joint_cov = Eigen::MatrixXd::Zero(7, 7);
  p.joint_cov.topLeftCorner<3, 3>() = Eigen::Vector3d(0.01, 0.36, 1e-4).asDiagonal();
  p.joint_cov.bottomRightCorner<4, 4>() = 0.0004 * Eigen::Matrix4d::Identity();
  p.obs_cov = Eigen::Vector2d(0.05 * 0.05, std::pow(DegToRad(1.0), 2)).asDiagonal();
  return p;
}

Eigen::Vector2d SeenFrom(const Pose2& robot, const Eigen::Vector2d& m) { return ObserveRangeBearing(robot, m); }

TEST(DataAssociation, JointCompatibilityFindsWhatNearestNeighbourGetsWrong) {
  // The robot is really 0.6 m to the left of its estimate, which shifts both observations
  // the same way: alone, the observation of landmark 11 looks nearest to landmark 10.
  AssociationProblem p = TwoLandmarks();
  const Pose2 truth{0, 0.6, 0};
  p.z = {SeenFrom(truth, {5, 0}), SeenFrom(truth, {5, 1})};
  p.signatures = {-1, -1};
  AssociationOptions o;
  o.method = AssociationMethod::kIcnn;
  const AssociationResult nn = Associate(p, o);
  EXPECT_EQ(nn.match[1], 0);  // wrong: observation of 11 paired with 10
  o.method = AssociationMethod::kJcbb;
  const AssociationResult jc = Associate(p, o);
  EXPECT_EQ(jc.match, (std::vector<int>{0, 1}));  // both right
  EXPECT_GT(jc.jcbb_nodes, 0);
}

TEST(DataAssociation, FarObservationsAreNewAndNearOnesAmbiguous) {
  AssociationProblem p = TwoLandmarks();
  p.joint_cov.topLeftCorner<3, 3>() = Eigen::Vector3d(1e-4, 1e-4, 1e-6).asDiagonal();
  p.z = {SeenFrom({0, 0, 0}, {5, 0.02}), SeenFrom({0, 0, 0}, {12, -6}), SeenFrom({0, 0, 0}, {5, 0.3})};
  p.signatures = {-1, -1, -1};
  for (AssociationMethod m : {AssociationMethod::kIcnn, AssociationMethod::kJcbb}) {
    AssociationOptions o;
    o.method = m;
    const AssociationResult r = Associate(p, o);
    EXPECT_EQ(r.match[0], 0);
    EXPECT_EQ(r.match[1], AssociationResult::kNew);
    EXPECT_EQ(r.match[2], AssociationResult::kDiscard);  // 0.3 m (3.3 sigma) from a landmark: neither
    EXPECT_EQ(r.ambiguous, 1);
  }
}

TEST(DataAssociation, KnownSignaturesAreGatedAgainstOutliers) {
  AssociationProblem p = TwoLandmarks();
  p.joint_cov.topLeftCorner<3, 3>() = Eigen::Vector3d(1e-4, 1e-4, 1e-6).asDiagonal();
  Eigen::Vector2d spurious = SeenFrom({0, 0, 0}, {5, 1});
  spurious(0) += 3.0;  // a range 3 m off, as MRCLAM's camera sometimes reports
  p.z = {SeenFrom({0, 0, 0}, {5, 0}), spurious, SeenFrom({0, 0, 0}, {2, 2}), SeenFrom({0, 0, 0}, {1, 1})};
  p.signatures = {10, 11, 42, -1};
  AssociationOptions o;
  o.method = AssociationMethod::kKnown;
  const AssociationResult r = Associate(p, o);
  EXPECT_EQ(r.match[0], 0);
  EXPECT_EQ(r.match[1], AssociationResult::kDiscard);
  EXPECT_EQ(r.rejected_by_gate, 1);
  EXPECT_EQ(r.match[2], AssociationResult::kNew);  // signature 42 is not in the map yet
  EXPECT_EQ(r.match[3], AssociationResult::kDiscard);
  EXPECT_EQ(r.unidentified, 1);
}

TEST(DataAssociation, MahalanobisDistanceMatchesAHandComputation) {
  AssociationProblem p;
  p.robot = {0, 0, 0};
  p.candidates = {1};
  p.means = {{4, 0}};
  p.joint_cov = Eigen::MatrixXd::Zero(5, 5);  // everything certain: S = R
  p.obs_cov = Eigen::Vector2d(0.01, 0.0004).asDiagonal();
  p.z = {{4.2, 0.04}};
  // nu = (0.2, 0.04): d2 = 0.04 / 0.01 + 0.0016 / 0.0004 = 8.
  Eigen::Vector2d nu;
  EXPECT_NEAR(MahalanobisSquared(p, 0, 0, &nu), 8.0, 1e-9);
  EXPECT_NEAR(nu(0), 0.2, 1e-12);
}

}  // namespace
}  // namespace mapmesh
