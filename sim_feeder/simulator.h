#pragma once
// The simulated world: unicycle robots following their paths among point landmarks, with
// noisy odometry, noisy range-bearing scans, ground truth and radio links. Deterministic
// for a given scenario: every robot draws from its own generator seeded from the scenario
// seed and its id, so a robot's streams do not depend on how many robots run.

#include <random>
#include <vector>

#include "common/config/scenario.h"
#include "sim_feeder/feed_source.h"
#include "sim_feeder/radio_model.h"
#include "sim_feeder/robot_sim.h"
#include "sim_feeder/world.h"

namespace mapmesh {

class Simulator : public FeedSource {
 public:
  // Robots with path type park walk a footpath of the world there and back.
  Simulator(const Scenario& scenario, World world);
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  bool Done() const override;
  // Step 0 is the initial instant (truth and links only); each later step advances one
  // control period and carries scans every scan_every_steps. A robot's odometry comes every
  // motion.odometry_every_steps steps (and at the last step): the mean of the steps' noisy
  // controls over their time, as an odometer integrating its encoders reports it. The noise
  // of each step is drawn alike whatever that rate, so runs at two odometry rates share their
  // truth and their draws.
  FeedBatch Next() override;
  const WorldTruth& Truth() const override { return truth_; }

 private:
  struct Robot {
    const RobotSpec* spec;
    Pose2 pose;
    FollowerState follower;
    std::mt19937_64 rng;
    std::mt19937_64 sight_rng;  // robot sightings: a stream of their own
    std::uint32_t odom_seq = 0;
    std::uint32_t scan_seq = 0;
    std::uint32_t start_scans = 0;  // taken from the start pose: announced by the first odometry
    // The odometry interval being gathered (motion.odometry_every_steps): steps, the sums of
    // their noisy controls, and the scans taken in it.
    int steps = 0;
    double sum_v = 0.0, sum_w = 0.0;
    std::uint32_t scans = 0;
  };
  // One scan of robot r from its true pose at `stamp`.
  Scan Sense(Robot& r, double stamp);
  RadioLinks Links(double stamp) const;
  // Appends to every scan of this step the other robots its robot sees (at their poses now).
  void SenseRobots(std::vector<Scan>& scans, std::size_t first);

  Scenario scenario_;
  RadioModel radio_;  // seeded by the scenario
  WorldTruth truth_;
  std::vector<Robot> robots_;
  std::uint64_t step_ = 0;
  std::uint64_t last_step_ = 0;
  double dt_;
  double next_links_s_ = 0.0;
  std::vector<int> seen_scratch_;
};

}  // namespace mapmesh
