#pragma once
// The thesis's alignment experiments (5.1.1, Figs. 46 and 48-53) on synthetic maps, each
// written as a CSV into a directory; scripts/plots/alignment.py draws them.

#include <cstdint>
#include <string>

namespace mapmesh::lab {

struct ThesisAlignmentOptions {
  int trials = 50;  // per point of every curve
  std::uint64_t seed = 1;
};

// Writes fig45_overlap.csv (the layouts: one pair per overlap ratio), fig46_similarity.csv, fig48_noise.csv, fig49_51_match_ratio.csv, fig50_transforms.csv
// and fig52_53_distance.csv into dir (created). Progress goes to stderr.
void RunThesisAlignment(const std::string& dir, const ThesisAlignmentOptions& options);

}  // namespace mapmesh::lab
