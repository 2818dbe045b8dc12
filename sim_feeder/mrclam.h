#pragma once
// Replay of the UTIAS MRCLAM datasets (Leung et al., IJRR 2011): 5 robots, 15 barcoded
// landmarks, Vicon ground truth (dataset 1 ships without robot ground truth).

#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "sim_feeder/replay_source.h"

namespace mapmesh {

// Reads dir (a MRCLAM_DatasetN folder) for the scenario's robots and turns it into streams:
// - time is rebased so the earliest odometry or measurement of the run is t = 0;
// - odometry row i (commanded v, w from its time until the next row's) becomes one interval
//   ending at the next row's time; with source.odometry_delay_s, commands take effect that
//   much later than their timestamps (the robots' response lag); rows repeating a timestamp are merged (counted); a
//   zero-motion interval is put first when a measurement precedes the first row;
// - measurement rows with the same time form one scan; barcodes of landmarks (subjects
//   6-20) become landmark observations with signature subject - 6 when the scenario shares
//   signatures; barcodes of robots (1-5) become robot sightings with signature = robot id;
//   unknown barcodes are dropped and counted;
// - ground truth (if present) is thinned to 10 Hz.
// Throws DatasetError naming the file (and line) on a missing or malformed file.
ReplayData LoadMrclam(const std::string& dir, const Scenario& scenario);

}  // namespace mapmesh
