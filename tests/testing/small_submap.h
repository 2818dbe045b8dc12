#pragma once
// A small valid closed submap for tests of what holds, relays and saves submaps (issue J1): two
// landmarks (keys 3 and 4), every entry of x equal to `x`, covariance 0.01 I, open from
// 10 index s to 10 index + 9 s.

#include <gtest/gtest.h>

#include <Eigen/Core>

#include "common/map/submap_codec.h"

namespace mapmesh::testing {

inline WireSubmap SmallSubmap(RobotId robot, std::uint32_t incarnation, std::uint32_t index, double x = 1.0) {
  WireSubmap s;
  s.id = {robot, incarnation, index};
  s.opened_s = 10.0 * index;
  s.closed_s = 10.0 * index + 9.0;
  s.keys = {3, 4};
  s.x = Eigen::VectorXd::Constant(7, x);
  EXPECT_TRUE(s.SetCovariance(Eigen::MatrixXd::Identity(7, 7) * 0.01));
  return s;
}

}  // namespace mapmesh::testing
