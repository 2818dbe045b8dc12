#pragma once
// Replay of the Victoria Park dataset (Guivant & Nebot 2001) as K virtual robots: the run is
// cut into K consecutive time segments (sharing overlap_s with their neighbours), and all K
// are played at once, each from scenario time 0 and from its own unknown start pose.

#include <string>

#include "common/config/scenario.h"
#include "sim_feeder/replay_source.h"

namespace mapmesh {

// Reads dir (inputs.dat, measurements.dat, gps.dat):
// - input row i (encoder speed, steering) holds over the interval since the previous row;
// - measurements with the same time form one scan; bearings are turned from the laser frame
//   (0 to pi, pi/2 ahead) to the vehicle frame (subtract pi/2); tree diameters are dropped;
//   no identities (signature -1);
// - GPS positions are the reference trajectory (headings unknown).
// Throws DatasetError naming the file (and line) on a missing or malformed file.
ReplayData LoadVictoriaPark(const std::string& dir, const Scenario& scenario);

}  // namespace mapmesh
