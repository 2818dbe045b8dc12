#pragma once
// The limit beside every run: from a scenario and its seed (the feeder's own streams, read in
// process), the centralized batch optimum of all robots' data with what the agents know of
// their starts (none: the fair limit), the same with every robot's true start (what no agent
// knows), each robot's single-robot batch optimum, and the known-pose map
// (common/slam/batch_slam.h), each scored against the truth. docs/EXPERIMENTS.md "The limit".

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "common/map/landmark_map.h"
#include "common/slam/batch_slam.h"

namespace mapmesh::lab {

struct ReferenceOptions {
  std::string datasets_root;
  // The loss on each observation; nullopt: by the data, none (Gaussian noise, least squares is
  // the optimum) for simulated worlds, Cauchy at 2 sigma for real datasets (heavy-tailed ranges).
  std::optional<RobustKernel> robust;
  bool known_pose = true;    // also the known-pose map
  bool known_starts = true;  // also the centralized optimum with every true start (central_known_starts)
  // Each listed robot's data up to this scenario time only (the others' whole): the information
  // that reached one agent by the end of its run, when it is less than the whole run's.
  std::map<RobotId, double> until;
  // Also solve the fair optimum from the truth (the true poses at every node and the true
  // landmarks), to check that the solve from the robots' own solutions reaches the same cost.
  bool check_start = false;
};

// One reference map and how it scores against the truth.
struct ReferenceMap {
  BatchSolution solution;
  double solve_s = 0.0;  // wall seconds of its solves
  bool evaluated = false;
  int landmarks = 0, matched = 0;
  double rmse_aligned_m = 0.0;   // after a rigid fit of the whole map to the truth
  std::optional<double> rmse_m;  // in the world frame, when the map is in it (true starts)
  double nees_mean = 0.0;        // in the world frame when it is, else after the fit
  double consistent_ratio = 0.0;
  // check_start: the same problem solved from the truth (its final cost; nullopt when not asked
  // for or without true poses).
  std::optional<LevenbergMarquardtReport> from_truth;
};

struct Reference {
  bool available = false;
  std::string why_none;                 // when not available
  std::string loss;                     // "none", "huber 1.345", "cauchy 2"
  std::map<RobotId, double> until;      // the robots whose data stops early (ReferenceOptions::until)
  ReferenceMap central;                 // the fair optimum: no robot's start known (each component's gauge)
  ReferenceMap central_known_starts;    // every robot's true start known ...
  bool has_known_starts = false;        // ... when computed (ReferenceOptions::known_starts)
  std::map<RobotId, ReferenceMap> own;  // each robot's single-robot batch
  std::optional<ReferenceMap> known_pose;
  std::map<RobotId, ReferenceMap> own_known_pose;  // each robot's own observations at its true poses
  std::string known_pose_why_none;                 // when known_pose is not set
  std::vector<Eigen::Vector2d> landmark_truth;
  std::vector<int> seen;
  double total_s = 0.0;  // wall seconds, reading the streams included
};

// Every robot's batch log from the scenario's streams, as its agent receives them (through the
// agent's SensorSync, its motion model, noise and range limits), with the landmarks'
// identities (the simulator's, or the dataset's barcodes) whether or not the scenario shares
// them; and each robot's true poses when known.
struct ReferenceInput {
  std::vector<BatchRobotLog> logs;
  // The robots' sightings of each other that the agents use (agent.align_by with rendezvous),
  // each between the two robots' nodes at its time (the logs hold a node there).
  std::vector<BatchSighting> sightings;
  int sightings_without_pose = 0;                     // outside the other robot's stream: left out
  std::map<RobotId, std::vector<GroundTruth>> truth;  // each from its start pose, when known
  std::vector<Eigen::Vector2d> landmark_truth;
  std::vector<int> seen;
  bool headings_known = true;
};
ReferenceInput ReadReferenceInput(const Scenario& scenario, const std::string& datasets_root);

// The reference of a run: nothing (with the reason) when the data carries no landmark
// identities (Victoria Park) or no landmark truth.
Reference ComputeReference(const Scenario& scenario, const ReferenceOptions& options);

}  // namespace mapmesh::lab
