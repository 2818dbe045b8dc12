#include "agent/robot_writers.h"

#include <gtest/gtest.h>

namespace mapmesh {
namespace {

TEST(RobotWriters, TheFirstWriterTakenSpeaksForTheRobotIncarnation) {
  RobotWriters w;
  EXPECT_TRUE(w.Admits(2, 1, "genuine"));
  EXPECT_TRUE(w.Admits(2, 1, "forger"));  // nothing bound yet: admitted until one is taken
  w.Bind(2, 1, "genuine");
  EXPECT_TRUE(w.Admits(2, 1, "genuine"));
  EXPECT_FALSE(w.Admits(2, 1, "forger"));
  w.Bind(2, 1, "forger");  // the first binding stays
  ASSERT_NE(w.Bound(2, 1), nullptr);
  EXPECT_EQ(*w.Bound(2, 1), "genuine");
}

TEST(RobotWriters, EachRobotIncarnationIsBoundApart) {
  RobotWriters w;
  w.Bind(2, 1, "a");
  EXPECT_TRUE(w.Admits(3, 1, "b"));  // another robot
  EXPECT_TRUE(w.Admits(2, 2, "b"));  // a restart: a new process, a new writer
  w.Bind(2, 2, "b");
  EXPECT_FALSE(w.Admits(2, 2, "a"));
  EXPECT_FALSE(w.Admits(2, 1, "b"));
}

TEST(RobotWriters, AnUnknownWriterIsNeitherRefusedNorBound) {
  RobotWriters w;
  w.Bind(2, 1, "");
  EXPECT_EQ(w.Bound(2, 1), nullptr);
  w.Bind(2, 1, "a");
  EXPECT_TRUE(w.Admits(2, 1, ""));
}

TEST(RobotWriters, BoundedPerRobotTheOldestIncarnationGoes) {
  RobotWriters w;
  for (std::uint32_t inc = 1; inc <= RobotWriters::kIncarnationsPerRobot + 3; ++inc)
    w.Bind(5, inc, "w" + std::to_string(inc));
  EXPECT_EQ(w.size(), RobotWriters::kIncarnationsPerRobot);
  EXPECT_EQ(w.Bound(5, 1), nullptr);
  const std::uint32_t last = RobotWriters::kIncarnationsPerRobot + 3;
  ASSERT_NE(w.Bound(5, last), nullptr);
  EXPECT_EQ(*w.Bound(5, last), "w" + std::to_string(last));
  w.Bind(6, 1, "x");  // another robot's room is its own
  EXPECT_EQ(w.size(), RobotWriters::kIncarnationsPerRobot + 1);
}

}  // namespace
}  // namespace mapmesh
