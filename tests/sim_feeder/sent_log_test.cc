#include "sim_feeder/sent_log.h"

#include <gtest/gtest.h>

#include "tests/testing/messages.h"

namespace mapmesh {
namespace {

constexpr auto O = testing::OdometryAt;
constexpr auto S = testing::ScanAt;

double StampOf(const SentLog::Message& m) {
  return std::visit([](const auto& x) { return x.stamp; }, m);
}

// Lockstep publishes an interval's scans before its held-back odometry; what the agent has not
// processed comes back in that same order, per robot.
TEST(SentLog, KeepsWhatIsNotProcessedInPublicationOrder) {
  SentLog log;
  log.Record(S(1, 0.25));
  log.Record(O(1, 0.1));
  log.Record(O(2, 0.1));
  log.Record(O(1, 0.2));
  log.Record(O(1, 0.3));
  log.Processed(1, 0.2);
  const auto left = log.Unprocessed(1);
  ASSERT_EQ(left.size(), 2u);
  EXPECT_TRUE(std::holds_alternative<Scan>(left[0]));
  EXPECT_DOUBLE_EQ(StampOf(left[0]), 0.25);
  EXPECT_DOUBLE_EQ(StampOf(left[1]), 0.3);
  EXPECT_EQ(log.size(2), 1u);
  log.Processed(1, 0.3);
  EXPECT_TRUE(log.Unprocessed(1).empty());
  log.Forget(2);
  EXPECT_EQ(log.size(2), 0u);
  EXPECT_TRUE(log.Unprocessed(7).empty());
}

}  // namespace
}  // namespace mapmesh
