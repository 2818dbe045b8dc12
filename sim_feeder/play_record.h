#pragma once
// What the feeder played: truth.json (the world and the true trajectories, sampled every
// feeder.truth_period_s) and feeder.json (what was published per robot, and for datasets what
// was read; who heard whom, as the link tables published said).

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "common/io/run_files.h"
#include "sim_feeder/feed_source.h"
#include "sim_feeder/radio_model.h"
#include "sim_feeder/replay_source.h"

namespace mapmesh {

class PlayRecord {
 public:
  PlayRecord(const Scenario& sc, const FeedSource& source, std::vector<ReplayCounts> counts);
  // A batch played: its ground truth, at the truth period, and how far the run got.
  void Add(const FeedBatch& b);
  void CountSent(const Scan& s) { ++scans_sent_[s.robot_id]; }
  void CountSent(const Odometry& o) { ++odom_sent_[o.robot_id]; }
  // Writes DIR/truth.json and DIR/feeder.json.
  // resent: sensor messages sent again to paused agents; replayed: to restarted agents.
  void Write(const std::string& dir, const FeedSource& source, double wall_s, bool interrupted,
             std::uint64_t resent = 0, std::uint64_t replayed = 0);

 private:
  const Scenario& sc_;
  std::vector<ReplayCounts> counts_;
  io::RunTruth truth_;
  std::map<RobotId, double> next_sample_;
  double played_until_ = 0.0;  // the stamp of the last batch played (where an interrupted run stopped)
  std::map<RobotId, std::uint32_t> odom_sent_, scans_sent_;
  LinkSpans links_;  // who heard whom, as published (feeder.json "links")
};

}  // namespace mapmesh
