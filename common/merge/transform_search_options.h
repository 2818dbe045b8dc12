#pragma once
// The settings of the searches for the transform between two maps that stand beside RANSAC
// (thesis 3.3.2.2.3-4; transform_search.h): which search runs, and each one's parameters.
// Included by map_alignment.h, whose AlignmentOptions holds them.

#include "common/types/choice.h"

namespace mapmesh {

// How AlignMaps searches for the transform (agent.align_search).
enum class TransformSearch {
  kRansac,                // RANSAC over the triangle matches' candidate pairs (thesis 3.3.2.2.2)
  kAdaptiveRandomWalk,    // Carpin's adaptive random walk (thesis Table 3), started from candidate pairs
  kIterativeTranslation,  // Saeedi's iterative translation search (thesis Table 4) at every rotation of a grid
};
inline constexpr ChoiceTable<TransformSearch, 3> kTransformSearch{{{TransformSearch::kRansac, "ransac"},
                                                                   {TransformSearch::kAdaptiveRandomWalk, "arw"},
                                                                   {TransformSearch::kIterativeTranslation, "its"}}};

// The overlap heuristic both searches maximise, Delta(A, T(B)): the sum over B's landmarks of
// exp(-d^2 / 2 s^2), d the distance from the moved landmark to the nearest of A's (0 beyond 3 s),
// s^2 = delta_sigma_m^2 + 2 sigma_b^2 (sigma_b the landmark's largest standard deviation as
// alignment compares it). A smooth count of B's landmarks that land on one of A's.
struct OverlapHeuristicOptions {
  double delta_sigma_m = 0.5;
};

// Adaptive random walk over (x, y, theta). Each restart pins a candidate pair (a, b), drawn
// uniformly from the triangle matches' candidates, at a uniformly drawn rotation: b lies on a,
// and the walk's rotation turns B about b. A proposal is the current sample plus a Gaussian
// step whose mean and covariance are those of the last `memory` accepted steps (plus a floor;
// the initial ones until `memory` steps were accepted). It is accepted when Delta grows, else
// with probability exp((Delta_new - Delta) / temperature) (the random selector).
struct RandomWalkOptions {
  int steps = 3000;              // proposals in all: the budget, shared by the restarts
  int steps_per_restart = 150;   // ... so steps / steps_per_restart restarts
  int memory = 10;               // M: the accepted steps the proposal adapts to
  double init_sigma_m = 0.5;     // the initial step's standard deviation along x and y ...
  double init_sigma_rad = 0.5;   // ... and in rotation
  double min_sigma_m = 0.02;     // a floor added to the adapted covariance ...
  double min_sigma_rad = 0.002;  // ... so that the walk never stops moving
  double max_sigma_scale = 2.0;  // the adapted standard deviations stay within this many initial ones
  double temperature = 1.0;      // the random selector's temperature (Delta units: landmarks)
};

// Iterative translation search at every rotation of a grid. Each landmark's direction n is the
// direction to its nearest neighbour in its own map (landmarks have no surface normals). At a
// rotation, every pair whose directions agree within start_epsilon votes for a translation;
// the best-voted cells seed the search, which then pairs each of B's landmarks with the
// closest of A's whose direction agrees within epsilon and which lies within gate_m, moves B
// by the mean difference of the pairs, and shrinks epsilon (Table 4), until the translation
// settles or max_iterations. The rotations' best translations are ranked by Delta.
struct TranslationSearchOptions {
  int rotations = 72;               // at least this many rotations, evenly spaced ...
  int max_rotations = 720;          // ... and more for a large map (B's radius times the step within gate_m),
                                    // at most this many
  double start_epsilon_rad = 0.35;  // epsilon at the start (also the voting's)
  double epsilon_shrink = 0.7;      // epsilon's factor per iteration ...
  double min_epsilon_rad = 0.1;     // ... down to this
  double gate_m = 1.5;              // a pair's landmarks lie at most this far apart
  double vote_cell_m = 1.0;         // translation votes are counted in cells this large
  int seeds_per_rotation = 3;       // the best-voted (3 x 3 cell) blocks, apart, that seed the search
  int max_iterations = 10;
  double converged_m = 1e-3;  // the translation moved less: stop (the thesis's J_thresh)
  int hypotheses = 8;         // the best ones by Delta are fitted and compared (ambiguity)
};

}  // namespace mapmesh
