#pragma once
// The JSON files of a run directory (truth.json, the agents' map files) and atomic file
// writing. Like config/ and transport/, this module does I/O and so sits outside the pure
// core; the core never includes it.

#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/config/resolved.h"
#include "common/geometry/pose2.h"
#include "common/geometry/pose_track.h"
#include "common/map/landmark_map.h"
#include "common/merge/global_map.h"
#include "common/types/messages.h"

namespace mapmesh::io {

using nlohmann::json;

// {"shape_sigma_m", "landmarks": [{"id", "signature", "x", "y", "cov": [xx, xy, yy]}...]}
json MapToJson(const LandmarkMap& map);
// MapToJson plus, per landmark, "origins": [[robot, incarnation, id]...] (the source-map
// landmarks fused into it, the first one its anchor; [robot, incarnation, id, 1] where the
// source map was a relayed global map, whose ids are its own; "origins_mark_relays": true
// says so, files written before have no mark), and the rebuild's counters.
json GlobalMapToJson(const GlobalMap& map);
// Throws std::runtime_error on a malformed document.
LandmarkMap MapFromJson(const json& j);
// An agent's estimated path (trajectory.json): {"frame_origin_stamp": s, or null before the
// frame is fixed, "poses": [[t, x, y, theta]...]}.
json TrajectoryToJson(const std::vector<PoseStamp>& poses, std::optional<double> frame_origin_stamp);

struct TruthSample {
  double t = 0.0;
  Pose2 pose;
};

struct RobotTruth {
  RobotId id = 0;
  std::optional<Pose2> start;           // unknown for datasets without ground truth
  std::vector<TruthSample> trajectory;  // may be empty
  // The true pose at time t, interpolated between samples (clamped to the ends); nullopt
  // without a trajectory.
  std::optional<Pose2> PoseAt(double t) const;
};

// truth.json: everything an evaluation needs to know about the world of a run.
struct RunTruth {
  std::string scenario;
  double duration_s = 0.0;
  std::vector<Eigen::Vector2d> landmarks;  // index = landmark id = signature
  std::vector<int> seen;                   // landmarks that any robot observed
  bool headings_known = true;              // false: trajectories are positions only (GPS)
  std::vector<RobotTruth> robots;
  const RobotTruth* Find(RobotId id) const;
};

json TruthToJson(const RunTruth& truth);
RunTruth TruthFromJson(const json& j);

// The resolved scenario as one JSON object by key path: numbers and booleans as such, strings
// as strings, a node read whole as its JSON value when it is one (lists of numbers), else as
// its YAML flow text.
json ResolvedToJson(const ResolvedScenario& resolved);

// A run file that could not be written: its path and the system's reason (errno: ENOSPC when
// the disk is full, EIO, EACCES, ...), as "PATH: REASON".
class WriteError : public std::runtime_error {
 public:
  WriteError(const std::string& path, int error);
  int error() const { return error_; }

 private:
  int error_;
};

// Writes path.tmp then renames it over path, so readers never see a partial file. On failure
// nothing is left behind (the temporary file is removed; path keeps what it held) and
// WriteError is thrown.
void WriteJsonAtomic(const std::string& path, const json& j);
void WriteFileAtomic(const std::string& path, const std::string& text);
// Appends one line to path (created when missing); WriteError on failure.
void AppendLine(const std::string& path, const std::string& line);
// Throws std::runtime_error naming the path on a missing file or a parse error.
json ReadJson(const std::string& path);

}  // namespace mapmesh::io
