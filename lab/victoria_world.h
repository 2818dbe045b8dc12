#pragma once
// A simulated Victoria Park (thesis 4.2.1.1, 4.2.2.1 and 5.3-5.4): the thesis drives simulated
// robots over Thrun's labelled Victoria Park tree map along trajectories cut from the car's run,
// so that every landmark has a ground truth. mapmesh derives both from the dataset itself: the
// landmark map is the whole run's own SLAM map (one robot, JCBB, trees within 30 m: the reference
// the Victoria Park replay is scored against), the trajectory is that run's estimated path. The
// path is cut into `segments` disjoint time spans (the thesis: eight), and the `robots` spans whose
// neighbourhoods share the most landmarks pairwise are kept (the thesis: four, chosen by their
// overlap). The result is a scenario the simulator drives with the thesis's motion and sensor
// models. This unit only reads a finished run and writes text; it runs nothing.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "lab/slam_experiment.h"

namespace mapmesh::lab {

struct VictoriaWorldOptions {
  int segments = 8;                 // disjoint time spans of the whole run
  int robots = 4;                   // spans kept
  double waypoint_spacing_m = 5.0;  // a waypoint every this far along a span
  double visible_m = 12.0;          // a landmark this close to a span's path is in its neighbourhood
  double min_segment_m = 50.0;      // spans shorter than this (the car parked) are never kept
};

struct VictoriaWorld {
  std::vector<Eigen::Vector2d> landmarks;           // in the whole run's frame (its start pose)
  std::vector<int> kept;                            // indices (0-based) of the spans kept, in time order
  std::vector<std::vector<Eigen::Vector2d>> paths;  // their waypoints, one path per kept span
  std::vector<double> length_m;                     // each kept path's length
  std::vector<int> neighbourhood;                   // landmarks near each kept path
  std::vector<std::vector<int>> shared;             // landmarks near both of two kept paths
};

// Cuts `whole` (one robot's run over the whole dataset) into spans and keeps the robots spans
// that maximise the smallest pairwise count of shared landmarks (ties: the largest total).
// Throws std::invalid_argument when the run is too short to give `robots` spans.
VictoriaWorld DeriveVictoriaWorld(const SlamRunResult& whole, const VictoriaWorldOptions& options);

// The landmark file (`x,y` rows) and a scenario that reads it from `landmarks_csv` (a path
// relative to the scenario file).
std::string VictoriaLandmarksCsv(const VictoriaWorld& world);
std::string VictoriaScenarioYaml(const VictoriaWorld& world, const std::string& landmarks_csv);

}  // namespace mapmesh::lab
