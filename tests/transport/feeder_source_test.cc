#include "common/transport/feeder_source.h"

#include <gtest/gtest.h>

namespace mapmesh::transport {
namespace {

const std::vector<std::string> kFeeder{kFeederPartition};

TEST(FeederSource, TrustsTheFirstWriterInTheFeedersPartitionOnly) {
  FeederSource s;
  const std::vector<std::string> none, robot{"robot2"}, two{kFeederPartition, "robot2"};
  // Outside the feeder's partition: refused whatever comes first, and no writer is trusted yet.
  EXPECT_EQ(s.Judge(nullptr, 5), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.Judge(&none, 5), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.Judge(&robot, 5), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.Judge(&two, 5), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.refused(), 4u);
  // The first writer there is the feeder from now on; a second one is refused, every time.
  EXPECT_EQ(s.Judge(&kFeeder, 7), FeederSource::Verdict::kFeeder);
  EXPECT_EQ(s.Judge(&kFeeder, 8), FeederSource::Verdict::kSecondWriter);
  EXPECT_EQ(s.Judge(&kFeeder, 7), FeederSource::Verdict::kFeeder);
  EXPECT_EQ(s.Judge(&kFeeder, 8), FeederSource::Verdict::kSecondWriter);
  EXPECT_EQ(s.Judge(&none, 7), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.refused(), 7u);
}

}  // namespace
}  // namespace mapmesh::transport
