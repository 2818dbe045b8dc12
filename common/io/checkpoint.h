#pragma once
// An agent's checkpoint file (agent_<id>/checkpoint.json): what a restarted agent resumes
// from. Writing, and loading with validation: a checkpoint is input like a received map, so
// it is refused with a one-line reason, never trusted, and the loader never throws, aborts
// or recurses on any file.
//
// Format: {"robot", "incarnation", "origin_stamp", "processed_until", "local": MAP,
// "global": MAP, "earlier": [{the same keys but "earlier", "submaps" and "peers"}...], "submaps":
// [SUBMAP...], "peers": [{"robot", "incarnation", "origin_stamp", "frame_stamp", "x", "y",
// "theta", "cov": [9 numbers, row by row]}...]} with MAP as in run_files.h and SUBMAP a closed submap's bytes as they travel
// (submap_codec.h) in base64, or in a secure run {"submap": those, "signature": its origin's
// signature in base64} (submap_origin.h; checked when the agent resumes). Older files nest earlier[] inside earlier entries; the loader
// flattens them in document order (an entry, then what it nests). Files without "submaps"
// (written before issue J1) hold none.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include <Eigen/Core>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"
#include "common/map/map_limits.h"
#include "common/types/messages.h"

namespace mapmesh {

// One incarnation of an agent as it was saved: its maps in its own frame.
struct IncarnationSnapshot {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  double origin_stamp = 0.0;     // s, when that incarnation's frame was fixed
  double processed_until = 0.0;  // s
  LandmarkMap local, global;     // in that incarnation's frame
};

// A peer incarnation's frame as an incarnation of the agent had placed it (issue R3): in the
// agent's frame that began at frame_stamp. A later incarnation whose frame began there too (the
// feeder replayed the robot's stream from the same start: continuity) is in that frame, so the
// transform holds for it as it is.
struct PeerAlignment {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  double origin_stamp = 0.0;  // s, when the peer's frame was fixed
  double frame_stamp = 0.0;   // s, when the agent's frame it is in was fixed
  Pose2 to_own;               // the peer's frame in the agent's
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
};

// What an agent saves to survive a kill: enough to re-merge everything it knew, through the
// same alignment path, after a restart (the restarted process starts a new map frame).
struct AgentCheckpoint : IncarnationSnapshot {
  // Earlier incarnations that had not been re-merged yet when this one was saved (flat).
  std::vector<IncarnationSnapshot> earlier;
  // The closed submaps the agent held (issue J1), each as it travels: its own of every
  // incarnation and its peers'. They are facts: a restarted agent holds its earlier chains and
  // relays and joins them as before, whether or not a peer kept them.
  // With the signatures they came with (secure runs; empty otherwise).
  std::vector<SubmapBlob> submaps;
  // The peers' frames it had placed, and those an earlier incarnation had that it did not place
  // again (issue R3: a restarted agent weighs them on the maps instead of searching afresh).
  std::vector<PeerAlignment> peers;
};

namespace io {

// Bounds on what a checkpoint file may hold; anything beyond is refused before or while
// parsing.
struct CheckpointLimits {
  std::uint64_t max_file_bytes = 256ull << 20;  // bytes; checked before the file is read
  std::size_t max_earlier = 64;                 // earlier incarnations in all, nested or not
  std::size_t max_landmarks = 100000;           // per map (as the wire codec's limit)
  std::size_t max_submaps = 20000;              // closed submaps held (agent.max_submaps_held's default) ...
  std::size_t max_peers = 65536;                // peer alignments (robots x agent.max_incarnations, with room)
  // The writer's bound, not checked when reading (max_file_bytes bounds that): the agent writes
  // at most this many submap bytes with their signatures, its own chains first (base64 in the
  // file: 171 MB of the 256 MB; agent.max_submap_bytes_held is below it).
  std::uint64_t max_submap_bytes = 128ull << 20;
  MapLimits submap_limits;                                       // each submap's, as a peer's (agent.peer_limits)
  double max_abs_coordinate_m = 1e5;                             // m, world bound on every landmark coordinate
  double max_stamp_s = std::numeric_limits<double>::infinity();  // s, no stamp after this (the run's end)
  // Deepest JSON nesting accepted: a checkpoint whose earlier[] entries nest max_earlier deep
  // reaches 2 * max_earlier + 5 levels; deeper text is refused before it is parsed.
  std::size_t MaxJsonDepth() const { return 2 * max_earlier + 8; }
};

// A checkpoint loaded and validated, or why not.
struct CheckpointLoad {
  std::optional<AgentCheckpoint> checkpoint;  // set when valid
  bool missing = false;                       // no file at the path (nothing else is wrong)
  std::string error;                          // one line naming the file and what is wrong
  bool ok() const { return checkpoint.has_value(); }
};

// The checkpoint as JSON, earlier incarnations as a flat array (each without "earlier").
nlohmann::json CheckpointToJson(const AgentCheckpoint& checkpoint);

// Parses and validates checkpoint text, naming it `name` in the reason. Valid means: the
// checkpoint and every earlier entry are robot `robot`'s; incarnations are distinct and none
// is `incarnation` (the resuming process's); stamps are finite, >= 0 and within
// limits.max_stamp_s; every landmark has a
// unique id in its map, a finite mean within limits.max_abs_coordinate_m and a finite,
// symmetric PSD covariance; every submap decodes (submap_codec.h: finite, positive definite),
// keeps limits.submap_limits, closes within limits.max_stamp_s, repeats no identity and is not
// the resuming incarnation's; every peer alignment is another robot's, once per incarnation,
// finite, within limits.max_abs_coordinate_m, with stamps as above and a symmetric PSD
// covariance; and the limits hold. Never throws, never aborts; work and stack
// are bounded by the text's size, not its nesting.
CheckpointLoad ParseCheckpoint(std::string_view text, std::string_view name, RobotId robot, std::uint32_t incarnation,
                               const CheckpointLimits& limits = {});

// Reads and parses the file at path as ParseCheckpoint does. A missing file gives `missing`;
// an unreadable one, a directory or one larger than limits.max_file_bytes an error (the size
// is checked before reading).
CheckpointLoad LoadCheckpoint(const std::string& path, RobotId robot, std::uint32_t incarnation,
                              const CheckpointLimits& limits = {});

}  // namespace io
}  // namespace mapmesh
