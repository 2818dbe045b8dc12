#pragma once
// Puts one robot's odometry and scans, which arrive on separate topics in any order, into
// time order. Odometry over (stamp - dt, stamp] announces how many scans fall inside it; the
// interval is processed once they are all there: the robot is moved to each scan's time, the
// scan applied, then moved to the end of the interval. Bad input (non-finite values, dt <= 0,
// time going backwards, empty scans) is counted and never reaches the estimator.
//
// With frame_at_first_landmark the estimator's frame is fixed only when it first maps a
// landmark: until then odometry is not applied (the robot stays at the origin) and the
// frame's origin moves with time. Odometry before any landmark carries no information about
// the map, only an error of the frame against the robot's start pose that nothing can later
// observe (the heading drift of the first half second turns the whole map). The map frame is
// then the robot's pose at that scan, the convention of keyframe SLAM (the first keyframe).

#include <cstdint>
#include <map>
#include <optional>

#include "common/slam/motion_model.h"
#include "common/types/messages.h"

namespace mapmesh {

struct SyncStats {
  std::uint32_t odom_processed = 0;
  std::uint32_t odom_rejected = 0;      // non-finite values, dt <= 0, or stamp going backwards
  std::uint32_t scans_processed = 0;    // applied (empty ones included: they are consumed)
  std::uint32_t scans_empty = 0;        // of which carried no observation: nothing to apply
  std::uint32_t scans_rejected = 0;     // non-finite stamp
  std::uint32_t scans_before_start = 0; // joining a running stream: the first interval's scans
  std::uint32_t scans_late = 0;         // arrived after their interval was processed
  std::uint32_t scans_missing = 0;      // announced by odometry but never arrived
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

  explicit SensorSync(Sink& sink, bool frame_at_first_landmark = false)
      : sink_(sink), frame_fixed_(!frame_at_first_landmark) {}

  void OnOdometry(const Odometry& odom);
  void OnScan(const Scan& scan);

  // All data with stamps up to here has been applied.
  double processed_until() const { return processed_until_; }
  // When the estimator's frame was fixed (the robot's pose then is its origin). With
  // frame_at_first_landmark, until frame_fixed() it is the time reached so far.
  std::optional<double> frame_origin_stamp() const { return frame_origin_stamp_; }
  // The frame will not move again: odometry is applied from here on.
  bool frame_fixed() const { return frame_fixed_; }
  const SyncStats& stats() const { return stats_; }

 private:
  void Drain();
  void ProcessInterval(const Odometry& odom);
  // Moves the robot by u over dt, reaching time `until`; before the frame is fixed, moves
  // the frame's origin there instead.
  void Move(const OdometryControl& u, double dt, double until);

  // An interval waits for its scans until odometry this many scenario seconds newer is
  // queued (longer than any lockstep window: see FeederOptions::lockstep_window_s).
  static constexpr double kMaxScanWaitS = 30.0;

  Sink& sink_;
  bool frame_fixed_;
  bool started_ = false;
  double processed_until_ = 0.0;
  std::optional<double> frame_origin_stamp_;
  std::map<double, Odometry> pending_odom_;
  std::multimap<double, Scan> pending_scans_;
  SyncStats stats_;
};

}  // namespace mapmesh
