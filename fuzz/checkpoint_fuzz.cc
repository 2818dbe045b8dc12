// libFuzzer target for the checkpoint loader (common/io/checkpoint.h): ParseCheckpoint on
// arbitrary text, under the default limits and under small ones. It must not throw (nothing is
// caught here), a refusal is one line naming the file, and an accepted checkpoint satisfies
// the documented validation (its submaps' too) and round-trips through CheckpointToJson.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <unordered_set>
#include <utility>

#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include "common/io/checkpoint.h"
#include "common/map/landmark_map.h"
#include "common/map/map_limits.h"
#include "common/map/submap_codec.h"
#include "common/map/submap_origin.h"
#include "fuzz/fuzz_check.h"

namespace mapmesh {
namespace {

// The resuming process the seeds are written for (fuzz/corpus_main.cc uses the same).
constexpr RobotId kRobot = 3;
constexpr std::uint32_t kIncarnation = 7;
constexpr std::string_view kName = "fuzz/agent_3/checkpoint.json";

bool SameMap(const LandmarkMap& a, const LandmarkMap& b) {
  if (a.size() != b.size() || a.shape_sigma_m != b.shape_sigma_m) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Landmark& x = a.landmarks[i];
    const Landmark& y = b.landmarks[i];
    if (x.id != y.id || x.signature != y.signature || x.mean != y.mean || x.cov != y.cov) return false;
  }
  return true;
}

bool SameSnapshot(const IncarnationSnapshot& a, const IncarnationSnapshot& b) {
  return a.robot == b.robot && a.incarnation == b.incarnation && a.origin_stamp == b.origin_stamp &&
         a.processed_until == b.processed_until && SameMap(a.local, b.local) && SameMap(a.global, b.global);
}

bool SameCheckpoint(const AgentCheckpoint& a, const AgentCheckpoint& b) {
  if (!SameSnapshot(a, b) || a.earlier.size() != b.earlier.size() || a.submaps != b.submaps) return false;
  for (std::size_t i = 0; i < a.earlier.size(); ++i) {
    if (!SameSnapshot(a.earlier[i], b.earlier[i])) return false;
  }
  if (a.peers.size() != b.peers.size()) return false;
  for (std::size_t i = 0; i < a.peers.size(); ++i) {
    const PeerAlignment &x = a.peers[i], &y = b.peers[i];
    if (x.robot != y.robot || x.incarnation != y.incarnation || x.origin_stamp != y.origin_stamp ||
        x.frame_stamp != y.frame_stamp || x.to_own.x != y.to_own.x || x.to_own.y != y.to_own.y ||
        x.to_own.theta != y.to_own.theta || x.cov != y.cov) {
      return false;
    }
  }
  return true;
}

// The documented validation of a map: within the limit, unique ids, finite means within the
// world bound, valid covariances, a finite non-negative shape precision.
void CheckMap(const LandmarkMap& map, const io::CheckpointLimits& limits) {
  MAPMESH_FUZZ_CHECK(map.size() <= limits.max_landmarks);
  MAPMESH_FUZZ_CHECK(std::isfinite(map.shape_sigma_m) && map.shape_sigma_m >= 0);
  std::unordered_set<std::uint32_t> ids;
  for (const Landmark& l : map.landmarks) {
    MAPMESH_FUZZ_CHECK(ids.insert(l.id).second);
    MAPMESH_FUZZ_CHECK(l.mean.allFinite());
    MAPMESH_FUZZ_CHECK(std::abs(l.mean.x()) <= limits.max_abs_coordinate_m);
    MAPMESH_FUZZ_CHECK(std::abs(l.mean.y()) <= limits.max_abs_coordinate_m);
    MAPMESH_FUZZ_CHECK(IsValidCovariance(l.cov));
  }
}

void CheckSnapshot(const IncarnationSnapshot& s, const io::CheckpointLimits& limits,
                   std::set<std::uint32_t>* incarnations) {
  MAPMESH_FUZZ_CHECK(s.robot == kRobot);
  MAPMESH_FUZZ_CHECK(s.incarnation != kIncarnation);
  MAPMESH_FUZZ_CHECK(incarnations->insert(s.incarnation).second);
  MAPMESH_FUZZ_CHECK(std::isfinite(s.origin_stamp) && s.origin_stamp >= 0);
  MAPMESH_FUZZ_CHECK(std::isfinite(s.processed_until) && s.processed_until >= 0);
  CheckMap(s.local, limits);
  CheckMap(s.global, limits);
}

// The documented validation of the submaps: within the limit, each decodes and keeps the submap
// limits, closes by the run's end, is not the resuming incarnation's, and no identity repeats.
// A signature, when there is one, holds 1 to kMaxSubmapSignatureBytes bytes.
void CheckSubmaps(const std::vector<SubmapBlob>& submaps, const io::CheckpointLimits& limits) {
  MAPMESH_FUZZ_CHECK(submaps.size() <= limits.max_submaps);
  std::set<SubmapId> ids;
  for (const SubmapBlob& blob : submaps) {
    const std::vector<std::uint8_t>& bytes = blob.bytes;
    MAPMESH_FUZZ_CHECK(blob.signature.size() <= kMaxSubmapSignatureBytes);
    const SubmapDecodeResult d = DecodeSubmap(bytes);
    MAPMESH_FUZZ_CHECK(d.ok());
    MAPMESH_FUZZ_CHECK(EncodeSubmap(d.submap) == bytes);
    MAPMESH_FUZZ_CHECK(CheckSubmapLimits(d.submap, limits.submap_limits) == MapLimitViolation::kNone);
    MAPMESH_FUZZ_CHECK(d.submap.closed_s <= limits.max_stamp_s);
    MAPMESH_FUZZ_CHECK(!(d.submap.id.robot == kRobot && d.submap.id.incarnation == kIncarnation));
    MAPMESH_FUZZ_CHECK(ids.insert(d.submap.id).second);
  }
}

// The documented validation of the peers' frames: within the limit, another robot's, once per
// incarnation, finite, within the world bound (theta within 4 rad), stamps >= 0, a symmetric
// covariance with no eigenvalue below -1e-12 of its largest entry (or of 1).
void CheckPeers(const std::vector<PeerAlignment>& peers, const io::CheckpointLimits& limits) {
  MAPMESH_FUZZ_CHECK(peers.size() <= limits.max_peers);
  std::set<std::pair<RobotId, std::uint32_t>> keys;
  for (const PeerAlignment& a : peers) {
    MAPMESH_FUZZ_CHECK(a.robot != kRobot);
    MAPMESH_FUZZ_CHECK(keys.insert({a.robot, a.incarnation}).second);
    MAPMESH_FUZZ_CHECK(std::isfinite(a.origin_stamp) && a.origin_stamp >= 0 && a.origin_stamp <= limits.max_stamp_s);
    MAPMESH_FUZZ_CHECK(std::isfinite(a.frame_stamp) && a.frame_stamp >= 0 && a.frame_stamp <= limits.max_stamp_s);
    MAPMESH_FUZZ_CHECK(std::abs(a.to_own.x) <= limits.max_abs_coordinate_m);
    MAPMESH_FUZZ_CHECK(std::abs(a.to_own.y) <= limits.max_abs_coordinate_m);
    MAPMESH_FUZZ_CHECK(std::abs(a.to_own.theta) <= 4.0);
    MAPMESH_FUZZ_CHECK(a.cov.allFinite());
    const double scale = std::max(1.0, a.cov.cwiseAbs().maxCoeff());
    MAPMESH_FUZZ_CHECK((a.cov - a.cov.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * scale);
    MAPMESH_FUZZ_CHECK(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(a.cov).eigenvalues().minCoeff() >=
                       -1e-12 * scale);
  }
}

void FuzzOne(std::string_view text, const io::CheckpointLimits& limits) {
  const io::CheckpointLoad load = io::ParseCheckpoint(text, kName, kRobot, kIncarnation, limits);
  MAPMESH_FUZZ_CHECK(!load.missing);
  if (!load.ok()) {
    // One line that names the file.
    MAPMESH_FUZZ_CHECK_SHOWING(load.error.starts_with(std::string(kName) + ": "), load.error.c_str());
    MAPMESH_FUZZ_CHECK_SHOWING(load.error.find_first_of("\n\r") == std::string::npos, load.error.c_str());
    MAPMESH_FUZZ_CHECK_SHOWING(load.error.size() <= 1024, load.error.c_str());
    return;
  }
  MAPMESH_FUZZ_CHECK(load.error.empty());
  const AgentCheckpoint& c = *load.checkpoint;
  std::set<std::uint32_t> incarnations;
  CheckSnapshot(c, limits, &incarnations);
  MAPMESH_FUZZ_CHECK(c.earlier.size() <= limits.max_earlier);
  for (const IncarnationSnapshot& e : c.earlier) CheckSnapshot(e, limits, &incarnations);
  CheckSubmaps(c.submaps, limits);
  CheckPeers(c.peers, limits);

  // What a checkpoint writes, it reads back unchanged.
  const std::string written = io::CheckpointToJson(c).dump();
  const io::CheckpointLoad again = io::ParseCheckpoint(written, kName, kRobot, kIncarnation, limits);
  MAPMESH_FUZZ_CHECK(again.ok());
  MAPMESH_FUZZ_CHECK(SameCheckpoint(c, *again.checkpoint));
  MAPMESH_FUZZ_CHECK(io::CheckpointToJson(*again.checkpoint).dump() == written);
}

}  // namespace
}  // namespace mapmesh

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  mapmesh::FuzzOne(text, mapmesh::io::CheckpointLimits{});
  mapmesh::io::CheckpointLimits small;
  small.max_earlier = 2;
  small.max_landmarks = 4;
  small.max_abs_coordinate_m = 100.0;
  small.max_submaps = 2;
  small.max_peers = 2;
  small.submap_limits.world_radius_m = 100.0;
  mapmesh::FuzzOne(text, small);
  return 0;
}
