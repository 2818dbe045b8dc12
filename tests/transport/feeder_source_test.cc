#include "common/transport/feeder_source.h"

#include <gtest/gtest.h>

namespace mapmesh::transport {
namespace {

const std::vector<std::string> kFeeder{kFeederPartition};

TEST(FeederSource, TrustsTheFirstWriterInTheFeedersPartitionOnly) {
  FeederSource s;
  const std::vector<std::string> none, robot{"robot2"}, two{kFeederPartition, "robot2"};
  // Outside the feeder's partition: refused whatever comes first, and no writer is trusted yet.
  const std::string a = "writer-a-guid-16", b = "writer-b-guid-16";
  EXPECT_EQ(s.Judge(nullptr, &a), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.Judge(&none, &a), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.Judge(&robot, &a), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.Judge(&two, &a), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.Judge(&kFeeder, nullptr), FeederSource::Verdict::kOutsidePartition);  // an unknown writer
  EXPECT_EQ(s.refused(), 5u);
  // The first writer there is the feeder from now on; a second one is refused, every time.
  EXPECT_EQ(s.Judge(&kFeeder, &a), FeederSource::Verdict::kFeeder);
  EXPECT_EQ(s.Judge(&kFeeder, &b), FeederSource::Verdict::kSecondWriter);
  EXPECT_EQ(s.Judge(&kFeeder, &a), FeederSource::Verdict::kFeeder);
  EXPECT_EQ(s.Judge(&kFeeder, &b), FeederSource::Verdict::kSecondWriter);
  EXPECT_EQ(s.Judge(&none, &a), FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(s.refused(), 8u);
}

}  // namespace
}  // namespace mapmesh::transport
