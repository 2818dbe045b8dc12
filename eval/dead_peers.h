#pragma once
// What an agent's global map holds of the peers that can no longer speak (killed, or silent at
// the end): for each, the last map the agent received of it, whether that map overlaps the
// agent's final local map by the exchange's own alignment criteria, and how many of the true
// landmarks it holds the global map holds too (by whichever route: the peer's map itself, or a
// relay's). The exchange promises that nothing learned is lost: every landmark of a map its
// alignment can place. "Overlaps" is told two ways: the alignment (AlignMaps, with the
// exchange's options) finds the true transform, on most of kAlignTries seeded tries; and, more
// loosely, verification at the true transform accepts (what a perfect search would find).

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <string>

#include "common/geometry/pose2.h"
#include "common/map/landmark_map.h"

namespace mapmesh {

inline constexpr int kAlignTries = 10;

struct HeldFromPeer {
  int landmarks = 0;      // true landmarks in the last map received from the peer
  int aligned_tries = 0;  // of kAlignTries, the alignments of it to our final local map that find the
                          // true transform (within 1 m at its centroid and 2 degrees)
  bool alignable() const { return 2 * aligned_tries > kAlignTries; }
  bool overlaps = false;  // it verifies against our final local map at the true transform
  std::string verdict;    // ... the alignment's verdict there
  int covered = 0;        // ... its landmarks laid on ground we mapped, and how many of them match
  int inliers = 0;
  int held = 0;  // of its true landmarks, those our global map holds too
};

// own_local, own_global: the agent's final maps, in its frame, whose true pose is own_origin;
// peer_map: the last local map received from the peer, in its frame (true pose peer_origin).
// Landmarks are matched to the truth as the evaluation does (MatchToTruth within gate_m).
HeldFromPeer CheckHeld(const LandmarkMap& own_local, const LandmarkMap& own_global, const Pose2& own_origin,
                       const LandmarkMap& peer_map, const Pose2& peer_origin, const std::vector<Eigen::Vector2d>& truth,
                       double gate_m);

}  // namespace mapmesh
