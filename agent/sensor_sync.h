#pragma once
// Puts one robot's odometry and scans, which arrive on separate topics in any order, into
// time order. Odometry over (stamp - dt, stamp] announces how many scans fall inside it; the
// interval is processed once they are all there: the robot is moved to each scan's time, the
// scan applied, then moved to the end of the interval. Bad input (non-finite values, dt <= 0,
// time going backwards, empty scans) is counted and never reaches the estimator.
//
// Stamps must be plausible: none beyond the run's end (when known), and none further than
// max_stamp_jump_s beyond the odometry received so far. An odometry message that jumps further
// is held until the next one continues it (its interval starts where the held one ends, and
// its sequence number follows): then both are taken, as after a stream resumes from a stall;
// otherwise the held one is refused. So one forged stamp cannot move the stream's clock ahead
// and freeze it. Sequence numbers only count (SequenceCount), for the messages taken: gaps as lost
// messages; a message out of sequence is counted so and judged by its stamp like any other; a
// forged number cannot move the count.
//
// With frame_at_first_landmark the estimator's frame is fixed only when it first maps a
// landmark: until then odometry is not applied (the robot stays at the origin) and the
// frame's origin moves with time. Odometry before any landmark carries no information about
// the map, only an error of the frame against the robot's start pose that nothing can later
// observe (the heading drift of the first half second turns the whole map). The map frame is
// then the robot's pose at that scan, the convention of keyframe SLAM (the first keyframe).

#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <optional>

#include "agent/sequence_count.h"
#include "common/options/sensor_sync_options.h"
#include "common/slam/motion_model.h"
#include "common/types/messages.h"

namespace mapmesh {

// Each stream's messages handed in are, exactly: received + duplicate + out_of_sequence +
// rejected + implausible (the odometry jump held at the end aside). The feeder's sent count
// is received + lost + before_join, but for a tail lost after the last message received.
struct SyncStats {
  std::uint32_t odom_received = 0;  // in sequence, first copies: the stream's messages this process got
  std::uint32_t odom_processed = 0;
  std::uint32_t odom_rejected = 0;          // non-finite values, dt <= 0, or stamp going backwards
  std::uint32_t odom_implausible = 0;       // stamp beyond the run's end, or a jump nothing continued
  std::uint32_t odometry_lost = 0;          // never arrived: gaps in the sequence numbers (SequenceCount)
  std::uint32_t odom_duplicate = 0;         // arrived again (sent again after a stall): ignored
  std::uint32_t odom_out_of_sequence = 0;   // behind the stream, or a lone number far ahead of it
  std::uint32_t odom_before_join = 0;       // sent before this process joined the stream (a restart)
  std::uint32_t scans_received = 0;         // in sequence, first copies
  std::uint32_t scans_implausible = 0;      // stamp beyond the run's end or the plausible window
  std::uint32_t scans_lost = 0;             // never arrived: gaps in the sequence numbers
  std::uint32_t scans_duplicate = 0;        // arrived again: ignored
  std::uint32_t scans_out_of_sequence = 0;  // behind the stream, or a lone number far ahead of it
  std::uint32_t scans_before_join = 0;      // sent before this process joined the stream
  std::uint32_t scans_processed = 0;        // applied (empty ones included: they are consumed)
  std::uint32_t scans_empty = 0;            // of which carried no observation: nothing to apply
  std::uint32_t scans_rejected = 0;         // non-finite stamp
  std::uint32_t scans_before_start = 0;     // joining a running stream: the first interval's scans
  std::uint32_t scans_late = 0;             // arrived after their interval was processed
  std::uint32_t scans_missing = 0;          // announced by odometry but never arrived
};

class SensorSync {
 public:
  // Receives the data in time order.
  class Sink {
   public:
    virtual ~Sink() = default;
    virtual void Move(const OdometryControl& u, double dt) = 0;
    virtual void ApplyScan(const Scan& scan, double stamp) = 0;
    // An odometry interval has been fully processed.
    virtual void IntervalDone(const Odometry& odom) = 0;
    // The estimator holds a landmark (see frame_at_first_landmark).
    virtual bool Mapped() const = 0;
  };

  using Options = SensorSyncOptions;

  SensorSync(Sink& sink, const Options& options)
      : sink_(sink), options_(options), frame_fixed_(!options.frame_at_first_landmark) {}
  explicit SensorSync(Sink& sink, bool frame_at_first_landmark = false)
      : SensorSync(sink, Options{frame_at_first_landmark}) {}

  void OnOdometry(const Odometry& odom);
  void OnScan(const Scan& scan);

  // All data with stamps up to here has been applied.
  double processed_until() const { return processed_until_; }
  // When the estimator's frame was fixed (the robot's pose then is its origin). With
  // frame_at_first_landmark, until frame_fixed() it is the time reached so far.
  std::optional<double> frame_origin_stamp() const { return frame_origin_stamp_; }
  // The frame will not move again: odometry is applied from here on.
  bool frame_fixed() const { return frame_fixed_; }
  SyncStats stats() const;

 private:
  // Takes a plausible odometry message into the queue.
  void Accept(const Odometry& odom);
  void Drain();
  void ProcessInterval(const Odometry& odom);
  // Moves the robot by u over dt, reaching time `until`; before the frame is fixed, moves
  // the frame's origin there instead.
  void Move(const OdometryControl& u, double dt, double until);

  // An interval waits for its scans until odometry this many scenario seconds newer is
  // queued (longer than any lockstep window: see FeederOptions::lockstep_window_s).
  static constexpr double kMaxScanWaitS = 30.0;

  Sink& sink_;
  Options options_;
  bool frame_fixed_;
  bool has_odom_ = false;         // some odometry was accepted ...
  double last_odom_stamp_ = 0.0;  // ... the latest, pending ones included
  std::optional<Odometry> jump_;  // a jump beyond the window, until the next message tells
  SequenceCount odom_seq_, scan_seq_;
  // The last odometry messages taken and scans received (sequence number, stamp), to know one
  // sent again.
  static constexpr std::size_t kRecent = 512;
  std::deque<std::pair<std::uint32_t, double>> recent_odom_, recent_scans_;
  bool started_ = false;
  double processed_until_ = 0.0;
  std::optional<double> frame_origin_stamp_;
  std::map<double, Odometry> pending_odom_;
  std::multimap<double, Scan> pending_scans_;
  SyncStats stats_;
};

}  // namespace mapmesh
