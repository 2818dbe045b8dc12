#include "agent/sensor_sync.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace mapmesh {
namespace {

// Writes down what reaches the estimator, in order.
class Log : public SensorSync::Sink {
 public:
  void Move(const OdometryControl& u, double dt) override { events.push_back("move " + Fmt(dt) + " v" + Fmt(u.v_mps)); }
  void ApplyScan(const Scan& s, double stamp) override {
    events.push_back("scan " + Fmt(stamp) + " n" + std::to_string(s.obs.size()));
  }
  void IntervalDone(const Odometry& o) override { events.push_back("done " + Fmt(o.stamp)); }
  bool Mapped() const override { return mapped; }
  static std::string Fmt(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.2f", v);
    return b;
  }
  std::vector<std::string> events;
  bool mapped = true;  // what the estimator answers after a scan
};

Odometry Odom(std::uint32_t seq, double stamp, double dt, std::uint32_t scans) {
  Odometry o;
  o.seq = seq;
  o.stamp = stamp;
  o.dt = dt;
  o.v = 1.0;
  o.scans_in_interval = scans;
  return o;
}

Scan ScanAt(double stamp, int n = 1) {
  Scan s;
  s.stamp = stamp;
  s.obs.resize(n, {3.0, 0.1, -1, ObservationKind::kLandmark});
  return s;
}

TEST(SensorSync, SplitsAnIntervalAtEachScan) {
  Log log;
  SensorSync sync(log);
  sync.OnScan(ScanAt(0.25));
  sync.OnScan(ScanAt(0.4));
  sync.OnOdometry(Odom(0, 0.5, 0.5, 2));
  EXPECT_EQ(log.events, (std::vector<std::string>{"move 0.25 v1.00", "scan 0.25 n1", "move 0.15 v1.00", "scan 0.40 n1",
                                                  "move 0.10 v1.00", "done 0.50"}));
  EXPECT_DOUBLE_EQ(sync.processed_until(), 0.5);
  EXPECT_DOUBLE_EQ(*sync.frame_origin_stamp(), 0.0);
}

// A scan at the opening stamp of the first interval (from the start pose) is applied there,
// before the robot moves.
TEST(SensorSync, AppliesAScanAtTheStreamsOriginBeforeMoving) {
  for (bool scan_first : {true, false}) {
    SCOPED_TRACE(scan_first);
    Log log;
    SensorSync sync(log);
    if (scan_first) sync.OnScan(ScanAt(0.0, 2));
    sync.OnOdometry(Odom(0, 0.1, 0.1, 1));
    if (!scan_first) {
      EXPECT_TRUE(log.events.empty());  // announced: waited for
      sync.OnScan(ScanAt(0.0, 2));
    }
    EXPECT_EQ(log.events, (std::vector<std::string>{"scan 0.00 n2", "move 0.10 v1.00", "done 0.10"}));
    EXPECT_EQ(sync.stats().scans_processed, 1u);
    EXPECT_EQ(sync.stats().scans_before_start + sync.stats().scans_late, 0u);
  }
}

// frame_at_first_landmark: no motion reaches the estimator before its first landmark, and the
// frame's origin is the time of the scan that mapped it.
TEST(SensorSync, FixesTheFrameWhenTheEstimatorFirstMapsALandmark) {
  Log log;
  log.mapped = false;
  SensorSync sync(log, /*frame_at_first_landmark=*/true);
  sync.OnOdometry(Odom(0, 0.5, 0.5, 0));  // no scan: the robot stays at the origin, which moves on
  EXPECT_FALSE(sync.frame_fixed());
  EXPECT_DOUBLE_EQ(*sync.frame_origin_stamp(), 0.5);
  sync.OnScan(ScanAt(0.7));  // applied, but it maps nothing (say every reading was out of range)
  sync.OnOdometry(Odom(1, 1.0, 0.5, 1));
  EXPECT_FALSE(sync.frame_fixed());
  EXPECT_DOUBLE_EQ(*sync.frame_origin_stamp(), 1.0);
  log.mapped = true;
  sync.OnScan(ScanAt(1.2));
  sync.OnOdometry(Odom(2, 1.5, 0.5, 1));
  EXPECT_TRUE(sync.frame_fixed());
  EXPECT_DOUBLE_EQ(*sync.frame_origin_stamp(), 1.2);
  sync.OnOdometry(Odom(3, 2.0, 0.5, 0));
  EXPECT_EQ(log.events, (std::vector<std::string>{"done 0.50", "scan 0.70 n1", "done 1.00", "scan 1.20 n1",
                                                  "move 0.30 v1.00", "done 1.50", "move 0.50 v1.00", "done 2.00"}));
  EXPECT_DOUBLE_EQ(*sync.frame_origin_stamp(), 1.2);

  // Without it the frame is the stream's start and every motion is applied.
  Log all;
  all.mapped = false;
  SensorSync from_start(all);
  from_start.OnOdometry(Odom(0, 0.5, 0.5, 0));
  EXPECT_TRUE(from_start.frame_fixed());
  EXPECT_DOUBLE_EQ(*from_start.frame_origin_stamp(), 0.0);
  EXPECT_EQ(all.events, (std::vector<std::string>{"move 0.50 v1.00", "done 0.50"}));
}

TEST(SensorSync, RejectsBadInputWithACountedReason) {
  Log log;
  SensorSync sync(log);
  sync.OnOdometry(Odom(0, 0.1, 0.1, 0));
  Odometry nan = Odom(1, 0.2, 0.1, 0);
  nan.w = std::numeric_limits<double>::infinity();
  sync.OnOdometry(nan);
  sync.OnOdometry(Odom(1, 0.05, 0.1, 0));  // time going backwards
  sync.OnOdometry(Odom(1, 0.3, -0.1, 0));  // negative dt
  EXPECT_EQ(sync.stats().odom_rejected, 3u);
  Scan bad = ScanAt(0.15);
  bad.stamp = std::nan("");
  sync.OnScan(bad);
  EXPECT_EQ(sync.stats().scans_rejected, 1u);
  sync.OnScan(ScanAt(0.05));  // its interval is done
  EXPECT_EQ(sync.stats().scans_late, 1u);
  sync.OnScan(ScanAt(0.15, 0));  // empty
  sync.OnOdometry(Odom(1, 0.2, 0.1, 1));
  EXPECT_EQ(sync.stats().scans_empty, 1u);
  EXPECT_EQ(sync.stats().scans_processed, 1u);
  for (const auto& e : log.events) EXPECT_EQ(e.rfind("scan", 0), std::string::npos) << e;
  EXPECT_EQ(sync.stats().odom_processed, 2u);
}

Odometry Seq(std::uint32_t seq, double stamp, double dt = 0.1) { return Odom(seq, stamp, dt, 0); }

// Odometry every 0.1 s, sequence numbers first to end - 1.
void Feed(SensorSync& sync, std::uint32_t first, std::uint32_t end) {
  for (std::uint32_t k = first; k < end; ++k) sync.OnOdometry(Seq(k, 0.1 * (k + 1)));
}

SensorSync::Options WithJump(double max_stamp_jump_s) {
  SensorSync::Options o;
  o.frame_at_first_landmark = false;
  o.max_stamp_jump_s = max_stamp_jump_s;
  return o;
}

// One odometry message stamped 1e9 among genuine ones: held (nothing continues it), refused,
// and the stream goes on as if it had never come.
TEST(SensorSync, AForgedStampIsRefusedAndTheStreamGoesOn) {
  Log log;
  SensorSync::Options o = WithJump(5.0);
  SensorSync sync(log, o);
  Feed(sync, 0, 5);
  sync.OnOdometry(Seq(5, 1e9));
  EXPECT_DOUBLE_EQ(sync.processed_until(), 0.5);
  Feed(sync, 5, 10);
  EXPECT_DOUBLE_EQ(sync.processed_until(), 1.0);
  EXPECT_EQ(sync.stats().odom_processed, 10u);
  EXPECT_EQ(sync.stats().odom_implausible, 1u);
  EXPECT_EQ(sync.stats().odometry_lost, 0u);
  EXPECT_EQ(sync.stats().odom_received, 10u);  // the stream's ten: the refused one is not of it
  // With the run's end known, such a stamp is refused at once; so is a scan beyond the window.
  o.max_stamp_s = 100.0;
  SensorSync bounded(log, o);
  bounded.OnOdometry(Seq(0, 0.1));
  bounded.OnOdometry(Seq(1, 1e9));
  EXPECT_EQ(bounded.stats().odom_implausible, 1u);
  bounded.OnScan(ScanAt(50.0));
  bounded.OnScan(ScanAt(-1.0));
  EXPECT_EQ(bounded.stats().scans_implausible, 2u);
  bounded.OnOdometry(Seq(2, 0.2));
  EXPECT_DOUBLE_EQ(bounded.processed_until(), 0.2);
}

// A stream that stalled (its reader paused, messages lost) resumes seconds later: the first
// message after the gap is held until the next one continues it, then both are taken, and the
// gap in sequence numbers is counted as lost.
TEST(SensorSync, AStreamThatResumesAfterAGapIsTakenAndItsLossCounted) {
  Log log;
  SensorSync sync(log, WithJump(2.0));
  Feed(sync, 0, 4);
  sync.OnOdometry(Seq(40, 4.1));
  EXPECT_DOUBLE_EQ(sync.processed_until(), 0.4);  // held
  sync.OnOdometry(Seq(41, 4.2));
  EXPECT_DOUBLE_EQ(sync.processed_until(), 4.2);
  EXPECT_EQ(sync.stats().odom_processed, 6u);
  EXPECT_EQ(sync.stats().odometry_lost, 36u);
  EXPECT_EQ(sync.stats().odom_implausible, 0u);
  // Within the window a gap is taken at once (and counted the same way).
  sync.OnOdometry(Seq(45, 4.6));
  EXPECT_DOUBLE_EQ(sync.processed_until(), 4.6);
  EXPECT_EQ(sync.stats().odometry_lost, 39u);
}

TEST(SensorSync, ScanSequenceGapsAreCountedAsLost) {
  Log log;
  SensorSync sync(log);
  for (std::uint32_t seq : {0u, 1u, 4u, 5u, 9u}) {
    Scan s = ScanAt(0.05 * (seq + 1));
    s.seq = seq;
    sync.OnScan(s);
  }
  EXPECT_EQ(sync.stats().scans_received, 5u);
  EXPECT_EQ(sync.stats().scans_lost, 5u);  // 2, 3, 6, 7, 8
}

// Issue R2: one glitched scan numbered 999999 (a plausible stamp, a reading 30 km away) made
// scans_lost 999 106, and real losses were never counted again. Now the count stays exact:
// handed in = received + duplicate + out_of_sequence + refused, sent = received + lost.
TEST(SensorSync, AGlitchedScanNumberLeavesTheLossCountExact) {
  Log log;
  SensorSync sync(log);
  std::uint32_t sent = 0;
  auto scan = [&](std::uint32_t seq, double stamp) {
    Scan s = ScanAt(stamp);
    s.seq = seq;
    sync.OnScan(s);
  };
  for (std::uint32_t i = 0; i < 20; ++i, ++sent) {
    if (i == 12 || i == 13) continue;  // lost on the way
    scan(i, 0.05 * i + 0.01);
    if (i == 5) {
      Scan glitch = ScanAt(0.05 * i + 0.02);
      glitch.seq = 999999;
      glitch.obs[0].range = 30000.0;
      sync.OnScan(glitch);
      sync.OnScan(glitch);  // and sent again
    }
  }
  const SyncStats st = sync.stats();
  EXPECT_EQ(st.scans_lost, 2u);
  EXPECT_EQ(st.scans_received, 18u);
  EXPECT_EQ(st.scans_received + st.scans_lost, sent);
  EXPECT_EQ(st.scans_out_of_sequence, 1u);
  EXPECT_EQ(st.scans_duplicate, 1u);
  EXPECT_EQ(st.scans_received + st.scans_duplicate + st.scans_out_of_sequence, 20u);  // all handed in
}

// After a stall the feeder sends again what the agent had not reported processed: what the
// agent had already (applied, or waiting) is ignored and counted as duplicate, the rest goes
// on as if nothing had happened.
TEST(SensorSync, MessagesSentAgainAreIgnoredOnce) {
  Log log;
  SensorSync sync(log);
  Scan s1 = ScanAt(0.15), s2 = ScanAt(0.35);
  s1.seq = 0;
  s2.seq = 1;
  sync.OnScan(s1);
  sync.OnOdometry(Odom(0, 0.2, 0.2, 1));
  sync.OnScan(s2);  // waiting for its odometry
  const std::vector<std::string> before = log.events;
  sync.OnScan(s1);
  sync.OnOdometry(Odom(0, 0.2, 0.2, 1));
  sync.OnScan(s2);
  EXPECT_EQ(log.events, before);
  EXPECT_EQ(sync.stats().scans_duplicate, 2u);
  EXPECT_EQ(sync.stats().odom_duplicate, 1u);
  EXPECT_EQ(sync.stats().odom_rejected + sync.stats().scans_late, 0u);
  sync.OnOdometry(Odom(1, 0.4, 0.2, 1));
  EXPECT_DOUBLE_EQ(sync.processed_until(), 0.4);
  EXPECT_EQ(sync.stats().scans_processed, 2u);
  EXPECT_EQ(sync.stats().odometry_lost + sync.stats().scans_lost, 0u);
}

}  // namespace
}  // namespace mapmesh
