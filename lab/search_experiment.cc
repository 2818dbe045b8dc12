#include "lab/search_experiment.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

#include "common/metrics/trajectory_metrics.h"

namespace mapmesh::lab {
namespace {

constexpr TransformSearch kSearches[] = {TransformSearch::kRansac, TransformSearch::kAdaptiveRandomWalk,
                                         TransformSearch::kIterativeTranslation};

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

}  // namespace

std::vector<SearchTrial> RunSearchComparison(const SearchComparisonOptions& options, const AlignmentOptions& align) {
  using Clock = std::chrono::steady_clock;
  std::vector<SearchTrial> out;
  for (std::size_t ov = 0; ov < options.overlaps.size(); ++ov) {
    MapPairOptions maps = options.maps;
    maps.overlap = options.overlaps[ov];
    for (int k = 0; k < options.trials; ++k) {
      // The same pairs for every search, and for every overlap the same seeds.
      const std::uint64_t seed = options.seed + static_cast<std::uint64_t>(k);
      std::mt19937_64 map_rng(seed);
      const MapPair pair = MakeMapPair(maps, map_rng);
      const std::set<std::pair<int, int>> truth(pair.true_pairs.begin(), pair.true_pairs.end());
      const Eigen::Vector2d centroid = Centroid(pair.b);
      for (TransformSearch search : kSearches) {
        AlignmentOptions o = align;
        o.search = search;
        std::mt19937_64 rng(seed * 1000003u + 17u);
        const auto t0 = Clock::now();
        const AlignmentResult r = AlignMaps(pair.a, pair.b, o, rng);
        const auto t1 = Clock::now();
        SearchTrial t;
        t.overlap = maps.overlap;
        t.trial = k;
        t.search = search;
        t.landmarks_a = static_cast<int>(pair.a.size());
        t.landmarks_b = static_cast<int>(pair.b.size());
        t.shared = static_cast<int>(pair.true_pairs.size());
        t.verdict = r.verdict;
        const TransformError e = CompareTransforms(r.transform, pair.truth, centroid);
        t.translation_error_m = e.translation_m;
        t.rotation_error_deg = RadToDeg(e.rotation_rad);
        t.correct = r.accepted() && e.translation_m <= 0.2 && t.rotation_error_deg <= 1.0;
        t.inliers = static_cast<int>(r.inliers.size());
        int good = 0;
        for (const auto& q : r.inliers) good += truth.count(q);
        t.inlier_precision = r.inliers.empty() ? 0.0 : static_cast<double>(good) / r.inliers.size();
        t.best_support = r.best_support;
        t.runner_up_support = r.runner_up_support;
        t.iterations = r.iterations;
        t.ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
        out.push_back(t);
      }
    }
    std::fprintf(stderr, "mapmesh-lab: search comparison, overlap %.2f done (%zu of %zu)\n", maps.overlap, ov + 1,
                 options.overlaps.size());
  }
  return out;
}

std::string SearchCsvHeader() {
  return "overlap,trial,search,landmarks_a,landmarks_b,shared,verdict,correct,translation_error_m,rotation_error_deg,"
         "inliers,inlier_precision,best_support,runner_up_support,iterations,ms";
}

std::string SearchCsvRow(const SearchTrial& t) {
  std::ostringstream s;
  s << t.overlap << ',' << t.trial << ',' << NameOf(kTransformSearch, t.search) << ',' << t.landmarks_a << ','
    << t.landmarks_b << ',' << t.shared << ',' << ToString(t.verdict) << ',' << (t.correct ? 1 : 0) << ','
    << t.translation_error_m << ',' << t.rotation_error_deg << ',' << t.inliers << ',' << t.inlier_precision << ','
    << t.best_support << ',' << t.runner_up_support << ',' << t.iterations << ',' << t.ms;
  return s.str();
}

std::string SearchSummary(const std::vector<SearchTrial>& trials) {
  std::map<std::pair<double, int>, std::vector<const SearchTrial*>> groups;
  for (const SearchTrial& t : trials) groups[{t.overlap, static_cast<int>(t.search)}].push_back(&t);
  std::ostringstream s;
  s << "| overlap | search | pairs | correct | accepted, wrong | translation error of accepted: median / max (m) | "
       "rotation error of accepted: median / max (deg) | time: median / p95 (ms) |\n"
    << "|---|---|---|---|---|---|---|---|\n";
  char line[512];
  for (const auto& [key, group] : groups) {
    int correct = 0, wrong = 0;
    std::vector<double> te, re, ms;
    for (const SearchTrial* t : group) {
      correct += t->correct;
      ms.push_back(t->ms);
      if (t->verdict != AlignmentVerdict::kAccepted) continue;
      wrong += !t->correct;
      te.push_back(t->translation_error_m);
      re.push_back(t->rotation_error_deg);
    }
    const double max_te = te.empty() ? 0.0 : *std::max_element(te.begin(), te.end());
    const double max_re = re.empty() ? 0.0 : *std::max_element(re.begin(), re.end());
    std::snprintf(line, sizeof line, "| %.0f %% | %s | %zu | %d | %d | %.3f / %.3f | %.3f / %.3f | %.2f / %.2f |\n",
                  100.0 * key.first,
                  std::string(NameOf(kTransformSearch, static_cast<TransformSearch>(key.second))).c_str(), group.size(),
                  correct, wrong, Quantile(te, 0.5), max_te, Quantile(re, 0.5), max_re, Quantile(ms, 0.5),
                  Quantile(ms, 0.95));
    s << line;
  }
  return s.str();
}

}  // namespace mapmesh::lab
