#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "common/transport/domain_lease.h"
#include "common/transport/session.h"
#include "common/transport/shutdown.h"
#include "common/transport/topics.h"
#include "common/transport/typed.h"

namespace mapmesh::transport {
namespace {

const char* kConfig = MAPMESH_SOURCE_DIR "/config/cyclonedds-loopback.xml";

// A private domain for this test process, with the shipped loopback config.
class TransportTest : public ::testing::Test {
 protected:
  DomainLease lease_;
  Session session_{lease_.id(), kConfig, kConfig};
  const Participant& p() { return session_.participant(); }

  // Takes from reader until n valid samples arrived or 5 s passed.
  template <typename T>
  std::vector<T> TakeN(Reader<T>& reader, std::size_t n) {
    std::vector<T> got;
    WaitSet ws(p());
    ws.AttachReader(reader.raw(), 1);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (got.size() < n && std::chrono::steady_clock::now() < deadline) {
      ws.Wait(0.1);
      for (auto& s : reader.Take()) {
        if (s.valid) got.push_back(s.value);
      }
    }
    return got;
  }
  template <typename T>
  void WaitMatched(const Writer<T>& w) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (w.raw().MatchedReaders() == 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    ASSERT_GT(w.raw().MatchedReaders(), 0u);
  }
};

TEST_F(TransportTest, SensorStreamsRoundTrip) {
  Writer<Odometry> wo(p(), OdomTopic(3), SensorQos());
  Reader<Odometry> ro(p(), OdomTopic(3), SensorQos());
  Writer<Scan> ws(p(), ScanTopic(3), SensorQos());
  Reader<Scan> rs(p(), ScanTopic(3), SensorQos());
  WaitMatched(wo);
  WaitMatched(ws);
  Odometry o{3, 7, 1.5, 0.1, 0.3, -0.2, 0.05, 1, true};
  for (int i = 0; i < 100; ++i) {
    o.seq = i;
    wo.Write(o);
  }
  Scan s{3, 4, 1.5, {{2.5, 0.25, 17, ObservationKind::kLandmark}, {4.0, -1.0, 2, ObservationKind::kRobot}}};
  ws.Write(s);
  const auto odoms = TakeN(ro, 100);
  ASSERT_EQ(odoms.size(), 100u);  // reliable keep-all: nothing lost
  for (int i = 0; i < 100; ++i) EXPECT_EQ(odoms[i].seq, static_cast<std::uint32_t>(i));
  EXPECT_EQ(odoms[5].robot_id, 3u);
  EXPECT_DOUBLE_EQ(odoms[5].w, -0.2);
  EXPECT_DOUBLE_EQ(odoms[5].steering, 0.05);
  EXPECT_TRUE(odoms[5].sync);
  EXPECT_EQ(odoms[5].scans_in_interval, 1u);
  const auto scans = TakeN(rs, 1);
  ASSERT_EQ(scans.size(), 1u);
  ASSERT_EQ(scans[0].obs.size(), 2u);
  EXPECT_FLOAT_EQ(scans[0].obs[0].range, 2.5f);
  EXPECT_EQ(scans[0].obs[0].signature, 17);
  EXPECT_EQ(scans[0].obs[1].kind, ObservationKind::kRobot);
}

// A reader that leaves and comes back is one current match but two in total: the feeder uses
// the total to notice an agent that re-subscribed.
TEST_F(TransportTest, WriterCountsCurrentAndTotalMatchedReaders) {
  Writer<Odometry> w(p(), OdomTopic(5), SensorQos());
  EXPECT_EQ(w.raw().MatchedReaders(), 0u);
  EXPECT_EQ(w.raw().TotalMatchedReaders(), 0u);
  {
    Reader<Odometry> r(p(), OdomTopic(5), SensorQos());
    WaitMatched(w);
    EXPECT_EQ(w.raw().TotalMatchedReaders(), 1u);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (w.raw().MatchedReaders() != 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_EQ(w.raw().MatchedReaders(), 0u);
  Reader<Odometry> again(p(), OdomTopic(5), SensorQos());
  WaitMatched(w);
  EXPECT_EQ(w.raw().MatchedReaders(), 1u);
  EXPECT_EQ(w.raw().TotalMatchedReaders(), 2u);
}

TEST_F(TransportTest, LinksTruthStatusRoundTrip) {
  Writer<RadioLinks> wl(p(), kLinksTopic, LinksQos());
  Reader<RadioLinks> rl(p(), kLinksTopic, LinksQos());
  Writer<AgentStatus> wst(p(), kStatusTopic, StatusQos());
  Reader<AgentStatus> rst(p(), kStatusTopic, StatusQos());
  Writer<GroundTruth> wt(p(), kTruthTopic, TruthQos());
  Reader<GroundTruth> rt(p(), kTruthTopic, TruthQos());
  WaitMatched(wl);
  WaitMatched(wst);
  WaitMatched(wt);
  wl.Write({2.0, {{1, 2}, {2, 5}}});
  AgentStatus st;
  st.robot_id = 4;
  st.incarnation = 9;
  st.processed_until = 12.5;
  st.bytes_sent = 1ULL << 40;
  st.peers_aligned = {1, 2, 3};
  st.peers_stale = {5};
  wst.Write(st);
  wt.Write({2, 1.0, 3.0, 4.0, 0.5});
  const auto links = TakeN(rl, 1);
  ASSERT_EQ(links.size(), 1u);
  EXPECT_EQ(links[0].links, (std::vector<Link>{{1, 2}, {2, 5}}));
  const auto sts = TakeN(rst, 1);
  ASSERT_EQ(sts.size(), 1u);
  EXPECT_EQ(sts[0].incarnation, 9u);
  EXPECT_EQ(sts[0].bytes_sent, 1ULL << 40);
  EXPECT_EQ(sts[0].peers_aligned, (std::vector<RobotId>{1, 2, 3}));
  EXPECT_EQ(sts[0].peers_stale, (std::vector<RobotId>{5}));
  const auto truths = TakeN(rt, 1);
  ASSERT_EQ(truths.size(), 1u);
  EXPECT_DOUBLE_EQ(truths[0].y, 4.0);
}

TEST_F(TransportTest, LateJoinerGetsTheLatestMapPerSenderAndKind) {
  Writer<MapMessage> w(p(), kMapTopic, MapQos());
  MapMessage m;
  m.robot_id = 2;
  m.incarnation = 4;
  m.origin_stamp = 1.5;
  m.payload = {1, 2, 3, 4, 5};
  for (std::uint32_t v = 1; v <= 3; ++v) {
    m.version = v;
    w.Write(m);
  }
  m.kind = MapKind::kGlobal;
  m.version = 7;
  w.Write(m);
  // A second participant joins after the writes (transient-local durability).
  Participant late(lease_.id());
  Reader<MapMessage> r(late, kMapTopic, MapQos());
  std::vector<MapMessage> got;
  WaitSet ws(late);
  ws.AttachReader(r.raw(), 1);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (got.size() < 2 && std::chrono::steady_clock::now() < deadline) {
    ws.Wait(0.1);
    for (auto& s : r.Take()) {
      if (s.valid) got.push_back(s.value);
    }
  }
  ASSERT_EQ(got.size(), 2u);  // keep-last 1 per (robot, kind)
  std::sort(got.begin(), got.end(), [](auto& a, auto& b) { return a.kind < b.kind; });
  EXPECT_EQ(got[0].version, 3u);
  EXPECT_EQ(got[0].incarnation, 4u);
  EXPECT_DOUBLE_EQ(got[0].origin_stamp, 1.5);
  EXPECT_EQ(got[0].payload, (std::vector<std::uint8_t>{1, 2, 3, 4, 5}));
  EXPECT_EQ(got[1].kind, MapKind::kGlobal);
  EXPECT_EQ(got[1].version, 7u);
}

TEST_F(TransportTest, GuardConditionWakesTheWaitSet) {
  GuardCondition g(p());
  WaitSet ws(p());
  ws.AttachGuard(g, 42);
  EXPECT_TRUE(ws.Wait(0.01).empty());
  std::thread t([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    g.Trigger();
  });
  const auto start = std::chrono::steady_clock::now();
  const auto tags = ws.Wait(10.0);
  t.join();
  ASSERT_EQ(tags.size(), 1u);
  EXPECT_EQ(tags[0], 42);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_TRUE(g.Triggered());
}

TEST(Transport, ErrorsCarryTheCallAndCycloneReason) {
  try {
    Check(DDS_RETCODE_BAD_PARAMETER, "dds_something");
    FAIL();
  } catch (const DdsError& e) {
    EXPECT_NE(std::string(e.what()).find("dds_something: "), std::string::npos);
    EXPECT_EQ(e.code(), DDS_RETCODE_BAD_PARAMETER);
  }
  EXPECT_EQ(Check(5, "ok"), 5);
}

TEST(DomainLease, ParallelLeasesGetDistinctIds) {
  DomainLease a, b, c;
  EXPECT_NE(a.id(), b.id());
  EXPECT_NE(b.id(), c.id());
  EXPECT_NE(a.id(), c.id());
  for (int id : {a.id(), b.id(), c.id()}) {
    EXPECT_GE(id, kFirstLeasedDomain);
    EXPECT_LE(id, kLastLeasedDomain);
  }
}

}  // namespace
}  // namespace mapmesh::transport
