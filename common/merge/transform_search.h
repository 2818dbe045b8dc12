#pragma once
// Searches for the transform between two landmark maps that stand beside RANSAC (thesis
// 3.3.2.2.3-4): Carpin's adaptive random walk (Table 3) and Saeedi's iterative translation
// search (Table 4). Both maximise an overlap heuristic Delta (transform_search_options.h), fit
// their best hypotheses to the landmarks they pair, and hand the best one's gated pairs to the
// refinement and acceptance tests RANSAC's answer goes through (alignment_fit.h, Conclude):
// a wrong alignment is refused the same way. The ambiguity test compares the best hypothesis
// with the best different one (sharing less than same_alignment_overlap of their pairs).
//
// Deviations from the thesis, for landmark maps whose frames differ by a rotation too:
// - ARW: the walk needs a start near an answer in a space of (x, y, theta) that is mostly
//   empty of overlap, so each restart pins one of the triangle matches' candidate pairs at a
//   random rotation (b on a) and walks from there, turning B about b; the budget is fixed.
// - ITS searches translation only (Table 4). Here it runs at every rotation of a grid whose step
//   moves B's farthest landmark by at most its gate; landmarks carry no normals, so a landmark's
//   direction is the one to its nearest neighbour in its own map; Table 4 starts from zero
//   translation (it assumes roughly aligned maps), here the best cells of translation votes of
//   direction-compatible pairs seed it; pairs are gated by distance (Table 4 takes the closest
//   compatible landmark however far); it stops when the translation settles (not J < J_thresh).
// - Both: the best hypotheses are fitted (a few rounds of nearest-neighbour pairing within the
//   search's gate and a rigid least-squares fit, rotation included) before their gated pairs
//   are counted, so that the grid's or the walk's resolution does not decide which pairs pass.

#include <random>
#include <vector>

#include "common/map/landmark_map.h"
#include "common/merge/map_alignment.h"

namespace mapmesh {

// Adaptive random walk from the candidate pairs, then the refinement and acceptance tests.
AlignmentResult RandomWalkAlign(const LandmarkMap& a, const LandmarkMap& b,
                                const std::vector<CandidatePair>& candidates, const AlignmentOptions& options,
                                std::mt19937_64& rng);

// Iterative translation search over a grid of rotations, then the refinement and acceptance
// tests. Deterministic: it draws nothing.
AlignmentResult TranslationSearchAlign(const LandmarkMap& a, const LandmarkMap& b, const AlignmentOptions& options);

// The overlap heuristic Delta(A, T(B)) of the options (on the maps as alignment compares them).
double OverlapHeuristic(const LandmarkMap& a, const LandmarkMap& b, const Pose2& t, const AlignmentOptions& options);

}  // namespace mapmesh
