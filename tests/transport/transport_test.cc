#include <gtest/gtest.h>

#include <map>

#include <chrono>
#include <thread>

#include "common/transport/domain_lease.h"
#include "common/transport/oversize_counter.h"
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
  Writer<AgentStatus> wst(p(), kStatusTopic, StatusQos(1.0));
  Reader<AgentStatus> rst(p(), kStatusTopic, StatusQos(1.0));
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

// In lockstep a map carries its publisher's sightings and answers of the tick: every field of
// each crosses the wire.
TEST_F(TransportTest, ALockstepMapCarriesItsSightings) {
  Writer<MapMessage> w(p(), kMapTopic, LockstepMapQos(1.0));
  Reader<MapMessage> r(p(), kMapTopic, LockstepMapQos(1.0));
  WaitMatched(w);
  MapMessage m;
  m.robot_id = 3;
  m.incarnation = 2;
  m.version = 7;
  m.tick = 11;
  m.payload = {9, 8, 7};
  Sighting s;
  s.robot_id = 3;
  s.incarnation = 2;
  s.other = 5;
  s.stamp = 10.25;
  s.x = 1.5;
  s.y = -2.5;
  s.theta = 0.75;
  s.cov = {1, 2, 3, 4, 5, 6};
  s.range = 4.125;
  s.bearing = -0.5;
  s.sigma_range = 0.1;
  s.sigma_bearing = 0.02;
  s.tick = 11;
  Sighting a = s;
  a.kind = SightingKind::kAnswer;
  a.other = 1;
  a.other_incarnation = 4;
  m.sightings = {s, a};
  w.Write(m);
  const auto got = TakeN(r, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].payload, m.payload);
  ASSERT_EQ(got[0].sightings.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    const Sighting& g = got[0].sightings[i];
    const Sighting& e = m.sightings[i];
    EXPECT_EQ(g.robot_id, e.robot_id);
    EXPECT_EQ(g.incarnation, e.incarnation);
    EXPECT_EQ(g.kind, e.kind);
    EXPECT_EQ(g.other, e.other);
    EXPECT_EQ(g.other_incarnation, e.other_incarnation);
    EXPECT_EQ(g.stamp, e.stamp);
    EXPECT_EQ(g.x, e.x);
    EXPECT_EQ(g.y, e.y);
    EXPECT_EQ(g.theta, e.theta);
    EXPECT_EQ(g.cov, e.cov);
    EXPECT_EQ(g.range, e.range);
    EXPECT_EQ(g.bearing, e.bearing);
    EXPECT_EQ(g.sigma_range, e.sigma_range);
    EXPECT_EQ(g.sigma_bearing, e.sigma_bearing);
    EXPECT_EQ(g.tick, e.tick);
  }
  // A realtime map carries none.
  m.sightings.clear();
  ++m.version;
  w.Write(m);
  const auto bare = TakeN(r, 1);
  ASSERT_EQ(bare.size(), 1u);
  EXPECT_TRUE(bare[0].sightings.empty());
}

// A local map carries the submap chains its publisher holds, the closed submaps it sends, its
// open one and where it placed other chains, each byte for byte (an empty submap too: the
// receiver's decoder refuses it, not the wire).
TEST_F(TransportTest, ALocalMapCarriesSubmapsAndTheChainsHeld) {
  Writer<MapMessage> w(p(), kMapTopic, LockstepMapQos(1.0));
  Reader<MapMessage> r(p(), kMapTopic, LockstepMapQos(1.0));
  WaitMatched(w);
  MapMessage m;
  m.robot_id = 4;
  m.incarnation = 1;
  m.version = 3;
  m.payload = {1, 2};
  m.submaps_held = {{4, 1, 7, 0.0}, {9, 2, 0, 12.25}, {12, 3, 4000000000u, 1e6}};
  m.own_submap_digests = {0x0123456789abcdefULL, 0, ~0ULL};
  m.submaps = {{{0x4d, 0x53, 1, 0, 255}, {}}, {{}, {1}}, {std::vector<std::uint8_t>(9000, 0xa5), {9, 8, 7}}};
  m.open_submap = {7, 6, 5, 4};
  m.open_submap_signature = std::vector<std::uint8_t>(72, 0x30);
  m.open_relayed = {{{3, 2, 1}, {}}, {std::vector<std::uint8_t>(5000, 0x5a), std::vector<std::uint8_t>(70, 2)}};
  m.placements = {{9, 2, -1.5, 2e3, 3.1}, {12, 3, 0.25, -7.0, -0.5}};
  w.Write(m);
  const auto got = TakeN(r, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].submaps_held, m.submaps_held);
  EXPECT_EQ(got[0].own_submap_digests, m.own_submap_digests);
  EXPECT_EQ(got[0].submaps, m.submaps);
  EXPECT_EQ(got[0].open_submap, m.open_submap);
  EXPECT_EQ(got[0].open_submap_signature, m.open_submap_signature);
  EXPECT_EQ(got[0].open_relayed, m.open_relayed);
  EXPECT_EQ(got[0].placements, m.placements);
  EXPECT_EQ(got[0].payload, m.payload);
}

// Agents write maps in their robot's partition and read every robot's: the reader learns each
// sample's writer partition, and SpeaksFor refuses a sample claiming another robot. A writer
// outside the robots' partitions is not matched at all.
TEST_F(TransportTest, ReadersKnowEachSamplesWriterPartition) {
  Writer<MapMessage> robot2(p(), kMapTopic, MapQos(1.0).Partition(RobotPartition(2)));
  Writer<MapMessage> unpartitioned(p(), kMapTopic, MapQos(1.0));
  Reader<MapMessage> r(p(), kMapTopic, MapQos(1.0).Partition(kEveryRobotPartition));
  WriterPartitions writers(r.raw());
  WaitMatched(robot2);
  EXPECT_EQ(unpartitioned.raw().MatchedReaders(), 0u);
  MapMessage m;
  m.payload = {1, 2, 3};
  WaitSet ws(p());
  ws.AttachReader(r.raw(), 1);
  std::map<RobotId, int> spoke, refused;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while ((spoke[2] == 0 || refused[3] == 0) && std::chrono::steady_clock::now() < deadline) {
    for (RobotId claimed : {2u, 3u}) {
      m.robot_id = claimed;
      ++m.version;
      robot2.Write(m);
      unpartitioned.Write(m);
    }
    ws.Wait(0.05);
    for (const auto& s : r.Take()) {
      if (!s.valid) continue;
      const std::vector<std::string>* parts = writers.Of(s.publication);
      ASSERT_NE(parts, nullptr);
      EXPECT_EQ(*parts, std::vector<std::string>{"robot2"});
      ++(SpeaksFor(parts, s.value.robot_id) ? spoke : refused)[s.value.robot_id];
    }
  }
  EXPECT_GT(spoke[2], 0);
  EXPECT_GT(refused[3], 0);
  EXPECT_EQ(spoke[3], 0);
  EXPECT_EQ(refused[2], 0);
  EXPECT_FALSE(SpeaksFor(nullptr, 2));
  const std::vector<std::string> two{"robot2", "robot3"};
  EXPECT_FALSE(SpeaksFor(&two, 2));  // one partition only
}

// Link tables (and ticks) are read from every partition, so that what is not the feeder's is seen
// and refused: the feeder's writer is trusted once its table is taken, a second writer in its
// partition and writers in the default or a robot's partition are refused.
TEST_F(TransportTest, OnlyTheFeedersLinkTablesAreTaken) {
  Reader<RadioLinks> r(p(), kLinksTopic, FeederTopicReader(LinksQos()));
  WriterPartitions writers(r.raw());
  const Participant others(lease_.id());  // (one participant's topic has one QoS)
  Writer<RadioLinks> feeder(others, kLinksTopic, FeederWriter(LinksQos()));
  Writer<RadioLinks> second(others, kLinksTopic, FeederWriter(LinksQos()));
  Writer<RadioLinks> plain(others, kLinksTopic, LinksQos());
  Writer<RadioLinks> robot(others, kLinksTopic, LinksQos().Partition(RobotPartition(3)));
  WaitMatched(feeder);
  WaitMatched(second);
  WaitMatched(plain);  // the reader's "" matches the default partition
  WaitMatched(robot);  // and its "*" every named one
  FeederSource source;
  std::map<double, FeederSource::Verdict> verdicts;  // by stamp: one writer each
  auto judge_until = [&](std::size_t n) {
    WaitSet ws(p());
    ws.AttachReader(r.raw(), 1);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (verdicts.size() < n && std::chrono::steady_clock::now() < deadline) {
      ws.Wait(0.1);
      for (const auto& s : r.Take()) {
        if (s.valid) verdicts[s.value.stamp] = source.Judge(writers.Of(s.publication), writers.GuidOf(s.publication));
      }
    }
    ASSERT_EQ(verdicts.size(), n);
  };
  feeder.Write({1.0, {{1, 2}}});
  judge_until(1);
  second.Write({2.0, {{1, 3}}});
  plain.Write({3.0, {{1, 4}}});
  robot.Write({4.0, {{1, 5}}});
  feeder.Write({5.0, {{1, 2}}});
  judge_until(5);
  EXPECT_EQ(verdicts[1.0], FeederSource::Verdict::kFeeder);
  EXPECT_EQ(verdicts[2.0], FeederSource::Verdict::kSecondWriter);
  EXPECT_EQ(verdicts[3.0], FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(verdicts[4.0], FeederSource::Verdict::kOutsidePartition);
  EXPECT_EQ(verdicts[5.0], FeederSource::Verdict::kFeeder);
  EXPECT_EQ(source.refused(), 3u);
}

// Maps are best-effort and volatile: a participant that joins later gets each sender's next
// map, not the ones sent before; what arrives comes in order, per (robot, kind).
TEST_F(TransportTest, LateJoinerGetsTheNextMapPerSenderAndKind) {
  Writer<MapMessage> w(p(), kMapTopic, MapQos(1.0));
  MapMessage m;
  m.robot_id = 2;
  m.incarnation = 4;
  m.origin_stamp = 1.5;
  m.payload = {1, 2, 3, 4, 5};
  m.version = 1;
  w.Write(m);  // before the reader exists: never delivered
  Participant late(lease_.id());
  Reader<MapMessage> r(late, kMapTopic, MapQos(1.0));
  WaitSet ws(late);
  ws.AttachReader(r.raw(), 1);
  std::map<MapKind, std::vector<MapMessage>> got;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  // The sender publishes periodically, as agents do, until both of its newest maps arrived.
  std::uint32_t version = 1;
  while ((got[MapKind::kLocal].empty() || got[MapKind::kGlobal].empty()) &&
         std::chrono::steady_clock::now() < deadline) {
    ++version;
    m.kind = MapKind::kLocal;
    m.version = version;
    w.Write(m);
    m.kind = MapKind::kGlobal;
    m.version = 100 + version;
    w.Write(m);
    ws.Wait(0.05);
    for (auto& s : r.Take()) {
      if (s.valid) got[s.value.kind].push_back(s.value);
    }
  }
  ASSERT_FALSE(got[MapKind::kLocal].empty());
  ASSERT_FALSE(got[MapKind::kGlobal].empty());
  for (const auto& [kind, maps] : got) {
    for (std::size_t i = 0; i < maps.size(); ++i) {
      EXPECT_GT(maps[i].version, kind == MapKind::kLocal ? 1u : 101u);  // none from before the join
      if (i > 0) {
        EXPECT_GT(maps[i].version, maps[i - 1].version);  // in order
      }
    }
  }
  const MapMessage& local = got[MapKind::kLocal].back();
  EXPECT_EQ(local.robot_id, 2u);
  EXPECT_EQ(local.incarnation, 4u);
  EXPECT_DOUBLE_EQ(local.origin_stamp, 1.5);
  EXPECT_EQ(local.payload, (std::vector<std::uint8_t>{1, 2, 3, 4, 5}));
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

// A session's max_sample_bytes is Cyclone's MaxSampleSize on top of the config: a larger sample
// goes nowhere (the writer refuses it, as a reader drops one from a writer without the bound:
// ddsi_receive.c drop_oversize), a smaller one as before.
TEST(Transport, SamplesBeyondTheSessionsMaxSampleSizeAreDropped) {
  DomainLease lease;
  Session session(lease.id(), kConfig, kConfig, 64 * 1024);
  Writer<MapMessage> w(session.participant(), kMapTopic, LockstepMapQos(1.0));
  Reader<MapMessage> r(session.participant(), kMapTopic, LockstepMapQos(1.0));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (w.raw().MatchedReaders() == 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_GT(w.raw().MatchedReaders(), 0u);
  MapMessage m;
  m.robot_id = 4;
  m.incarnation = 1;
  m.version = 1;
  m.payload = std::vector<std::uint8_t>(100 * 1024, 7);
  EXPECT_THROW(w.Write(m), DdsError);  // Cyclone refuses to write it (and warns)
  m.version = 2;
  m.payload = std::vector<std::uint8_t>(1024, 7);
  w.Write(m);
  // Reliable and in order: had the large one gone out, it would come first.
  std::vector<MapMessage> got;
  WaitSet ws(session.participant());
  ws.AttachReader(r.raw(), 1);
  while (got.empty() && std::chrono::steady_clock::now() < deadline + std::chrono::seconds(5)) {
    ws.Wait(0.1);
    for (auto& sample : r.Take()) {
      if (sample.valid) got.push_back(sample.value);
    }
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].version, 2u);
}

// What the agent counts of Cyclone's warnings: a received sample dropped for its size, not one
// its own writer refused.
TEST(Transport, OversizeCounterCountsOnlyReceivedSamplesDropped) {
  EXPECT_TRUE(OversizeCounter::IsReceivedOversizeDrop(
      "recvMC: dropping oversize (4048576 > 2886287) sample 1 from remote writer 1107db8:7e089443:3681e8aa:1802 "
      "mapmesh/map/mapmesh::msg::MapMessage"));
  EXPECT_FALSE(OversizeCounter::IsReceivedOversizeDrop(
      "dropping oversize (102472 > 65536) sample from local writer 1108838:acc78f67:d75f69f5:202 mapmesh/map"));
  EXPECT_FALSE(OversizeCounter::IsReceivedOversizeDrop("some other warning from remote writer"));
  const OversizeCounter counter;
  EXPECT_EQ(counter.received(), 0u);
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
