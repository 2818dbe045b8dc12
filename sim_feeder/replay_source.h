#pragma once
// Plays prepared per-robot streams (odometry, scans, ground truth) in time order, with
// radio links from the true positions: the common back end of the dataset replays.

#include <optional>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "sim_feeder/feed_source.h"
#include "sim_feeder/radio_model.h"

namespace mapmesh {

// One robot's streams, stamped in scenario seconds and sorted.
struct RobotStreams {
  RobotId id = 0;
  std::vector<Odometry> odom;  // seq from 0, scans_in_interval filled in
  std::vector<Scan> scans;
  std::vector<GroundTruth> truth;  // may be empty (no ground truth)
  std::optional<Pose2> start;      // true pose at the start of the first odometry interval
};

// What was read from the files, for the record (feeder.json).
struct ReplayCounts {
  RobotId id = 0;
  int odom_rows = 0;            // rows in the odometry file used
  int odom_duplicate_rows = 0;  // rows repeating the previous timestamp: merged
  int measurement_rows = 0;     // rows in the measurement file used
  int measurement_unknown = 0;  // rows whose barcode is no known subject: dropped
  int robot_sightings = 0;      // rows that see another robot
};

struct ReplayData {
  std::vector<RobotStreams> robots;
  std::vector<Eigen::Vector2d> landmarks;  // true landmarks (index = signature); may be empty
  std::vector<bool> seen;                  // per landmark: observed by a robot of the run
  bool headings_known = true;              // false: truth holds positions only (GPS)
  double duration_s = 0.0;
  std::vector<ReplayCounts> counts;
};

// Fills in scans_in_interval of each odometry message from the scan stamps.
void CountScansPerInterval(RobotStreams& r);

// Drops everything stamped after duration_s (datasets replayed in part).
void Truncate(ReplayData& data, double duration_s);

class ReplaySource : public FeedSource {
 public:
  // The radio's draws are seeded by `seed` (the scenario's).
  ReplaySource(ReplayData data, const RadioOptions& radio, std::uint64_t seed = 1);

  bool Done() const override;
  FeedBatch Next() override;
  const WorldTruth& Truth() const override { return truth_; }
  const ReplayData& data() const { return data_; }

 private:
  double NextStamp() const;
  // A robot's true position at t from its ground truth (clamped at the ends), if any.
  std::optional<Eigen::Vector2d> PositionAt(const RobotStreams& r, double t) const;

  ReplayData data_;
  RadioOptions radio_;
  RadioModel radio_model_;
  WorldTruth truth_;
  struct Cursor {
    std::size_t odom = 0, scan = 0, truth = 0;
  };
  std::vector<Cursor> cursors_;
  double next_links_s_ = 0.0;
};

}  // namespace mapmesh
