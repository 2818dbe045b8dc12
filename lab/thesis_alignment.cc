#include "lab/thesis_alignment.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <stdexcept>

#include "common/merge/map_alignment.h"
#include "common/metrics/trajectory_metrics.h"
#include "lab/synthetic_maps.h"

namespace mapmesh::lab {
namespace {

using Clock = std::chrono::steady_clock;

std::ofstream Open(const std::string& path, const std::string& header) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open for writing");
  f << header << '\n';
  return f;
}

struct Score {
  double thesis = 0.0;  // the thesis's success: share of the true pairs found as inliers
  double ours = 0.0;    // accepted and within 0.2 m (at B's centroid) and 1 deg
  double ms = 0.0;
};

Score ScoreOf(const AlignmentResult& r, const MapPair& p, double ms) {
  const std::set<std::pair<int, int>> truth(p.true_pairs.begin(), p.true_pairs.end());
  int found = 0;
  for (const auto& q : r.inliers) found += truth.count(q);
  Score s;
  s.thesis = truth.empty() ? 0.0 : static_cast<double>(found) / truth.size();
  const TransformError e = CompareTransforms(r.transform, p.truth, Centroid(p.b));
  s.ours = r.accepted() && e.translation_m <= 0.2 && RadToDeg(e.rotation_rad) <= 1.0 ? 1.0 : 0.0;
  s.ms = ms;
  return s;
}

// RANSAC alone (no triangles) over a candidate list whose share of true pairs is `ratio`:
// every true pair, plus wrong pairs drawn at random (thesis 5.1.1.3.3).
Score RansacOnly(const MapPair& p, double ratio, const AlignmentOptions& o, std::mt19937_64& rng) {
  std::vector<CandidatePair> cand;
  for (const auto& [a, b] : p.true_pairs) cand.push_back({a, b, 1});
  const int wrong = static_cast<int>(std::lround(cand.size() * (1.0 - ratio) / ratio));
  std::uniform_int_distribution<int> ua(0, static_cast<int>(p.a.size()) - 1), ub(0, static_cast<int>(p.b.size()) - 1);
  const std::set<std::pair<int, int>> truth(p.true_pairs.begin(), p.true_pairs.end());
  while (static_cast<int>(cand.size()) < static_cast<int>(p.true_pairs.size()) + wrong) {
    const int a = ua(rng), b = ub(rng);
    if (!truth.count({a, b})) cand.push_back({a, b, 1});
  }
  std::shuffle(cand.begin(), cand.end(), rng);
  const auto t0 = Clock::now();
  const AlignmentResult r = RansacAlign(p.a, p.b, cand, o, rng);
  return ScoreOf(r, p, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
}

MapPairOptions Maps(int n, double overlap, double sigma, bool random_frame) {
  MapPairOptions m;
  m.landmarks = n;
  m.overlap = overlap;
  m.sigma_m = sigma;
  m.density_per_m2 = 0.08;
  m.min_spacing_m = 1.0;
  m.random_frame = random_frame;
  return m;
}

// The thesis's RANSAC: Euclidean consensus with a 2 m gate, on the candidates only.
AlignmentOptions ThesisRansac() {
  AlignmentOptions o;
  o.distance = ConsensusDistance::kEuclidean;
  o.euclidean_gate_m = 2.0;
  o.guided_matching = false;
  return o;
}

// One updating line on a terminal, one line per experiment otherwise.
void Progress(const char* what, int done, int total) {
  if (isatty(STDERR_FILENO)) {
    std::fprintf(stderr, "\rmapmesh-lab: %s %d/%d   ", what, done, total);
    if (done == total) std::fprintf(stderr, "\n");
  } else if (done == total) {
    std::fprintf(stderr, "mapmesh-lab: %s done\n", what);
  }
}

}  // namespace

void RunThesisAlignment(const std::string& dir, const ThesisAlignmentOptions& opt) {
  std::filesystem::create_directories(dir);
  std::uint64_t seed = opt.seed;
  const int kTrials = opt.trials;

  {  // Fig. 45: how the overlap ratio is varied. One 200-landmark pair per ratio, B drawn in A's
     // frame (the experiments put it in a random one); shared: the landmark is in both maps.
    auto f = Open(dir + "/fig45_overlap.csv", "overlap,map,x,y,shared");
    for (double ov : {1.0, 0.7, 0.4, 0.1}) {
      std::mt19937_64 rng(seed);
      const MapPair p = MakeMapPair(Maps(200, ov, 0.1, false), rng);
      std::vector<char> shared_a(p.a.size(), 0), shared_b(p.b.size(), 0);
      for (const auto& [a, b] : p.true_pairs) shared_a[a] = shared_b[b] = 1;
      for (std::size_t i = 0; i < p.a.size(); ++i) {
        const Eigen::Vector2d& x = p.a.landmarks[i].mean;
        f << ov << ",A," << x.x() << ',' << x.y() << ',' << int{shared_a[i]} << '\n';
      }
      for (std::size_t i = 0; i < p.b.size(); ++i) {
        const Eigen::Vector2d x = p.truth.Apply(p.b.landmarks[i].mean);
        f << ov << ",B," << x.x() << ',' << x.y() << ',' << int{shared_b[i]} << '\n';
      }
    }
  }

  {  // Fig. 46: triangle similarity success (share of candidate pairs that are true) vs overlap.
    auto f = Open(dir + "/fig46_similarity.csv",
                  "landmarks,overlap,matcher,candidate_precision,true_candidates,correct_rate,median_ms");
    const std::vector<int> sizes{100, 200, 400, 1000};
    const std::vector<double> overlaps{0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0};
    int done = 0;
    for (int n : sizes) {
      for (double ov : overlaps) {
        for (const char* matcher : {"sorted_sides", "thesis"}) {
          const bool thesis = std::string(matcher) == "thesis";
          if (thesis && n > 400) continue;  // O(T1 T2): too slow to be worth it at 1000
          AlignmentOptions o;
          o.matcher = thesis ? TriangleMatcher::kThesisSimilarity : TriangleMatcher::kSortedSides;
          o.thesis_tau = std::exp(0.25);
          double precision = 0.0, true_cand = 0.0, correct = 0.0;
          std::vector<double> ms;
          for (int k = 0; k < kTrials; ++k) {
            std::mt19937_64 rng(seed++);
            const MapPair p = MakeMapPair(Maps(n, ov, 0.1, true), rng);
            const std::set<std::pair<int, int>> truth(p.true_pairs.begin(), p.true_pairs.end());
            const auto t0 = Clock::now();
            const AlignmentResult r = AlignMaps(p.a, p.b, o, rng);
            ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
            std::mt19937_64 rng2(seed * 7);
            const auto cand = MatchTriangles(p.a, p.b, o, rng2);
            int good = 0;
            for (const auto& c : cand) good += truth.count({c.a, c.b});
            precision += cand.empty() ? 0.0 : static_cast<double>(good) / cand.size();
            true_cand += good;
            correct += ScoreOf(r, p, 0).ours;
          }
          std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
          f << n << ',' << ov << ',' << matcher << ',' << precision / kTrials << ',' << true_cand / kTrials << ','
            << correct / kTrials << ',' << ms[ms.size() / 2] << '\n';
        }
        Progress("fig 46", ++done, static_cast<int>(sizes.size() * overlaps.size()));
      }
    }
  }

  const std::vector<double> sigmas{0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0};
  for (bool random_frame : {false, true}) {  // Fig. 48 (noise) and Fig. 50 (noise and random transforms)
    const std::string name = random_frame ? "/fig50_transforms.csv" : "/fig48_noise.csv";
    auto f = Open(dir + name, "landmarks,sigma_m,thesis_success,correct_rate,median_ms");
    int done = 0;
    for (int n : {100, 200, 400}) {
      for (double s : sigmas) {
        double thesis = 0.0, ours = 0.0;
        std::vector<double> ms;
        for (int k = 0; k < kTrials; ++k) {
          std::mt19937_64 rng(seed++);
          const MapPair p = MakeMapPair(Maps(n, 1.0, s, random_frame), rng);
          const Score sc = RansacOnly(p, 1.0, ThesisRansac(), rng);
          thesis += sc.thesis;
          ours += sc.ours;
          ms.push_back(sc.ms);
        }
        std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
        f << n << ',' << s << ',' << thesis / kTrials << ',' << ours / kTrials << ',' << ms[ms.size() / 2] << '\n';
        Progress(random_frame ? "fig 50" : "fig 48", ++done, 3 * static_cast<int>(sigmas.size()));
      }
    }
  }

  {  // Figs. 49 and 51: success and time vs the share of true pairs among the candidates.
    auto f = Open(dir + "/fig49_51_match_ratio.csv", "landmarks,match_ratio,thesis_success,correct_rate,median_ms");
    const std::vector<double> ratios{0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0};
    int done = 0;
    for (int n : {200, 400}) {
      for (double ratio : ratios) {
        double thesis = 0.0, ours = 0.0;
        std::vector<double> ms;
        for (int k = 0; k < kTrials; ++k) {
          std::mt19937_64 rng(seed++);
          const MapPair p = MakeMapPair(Maps(n, 1.0, 0.6, true), rng);
          const Score sc = RansacOnly(p, ratio, ThesisRansac(), rng);
          thesis += sc.thesis;
          ours += sc.ours;
          ms.push_back(sc.ms);
        }
        std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
        f << n << ',' << ratio << ',' << thesis / kTrials << ',' << ours / kTrials << ',' << ms[ms.size() / 2] << '\n';
        Progress("figs 49/51", ++done, 2 * static_cast<int>(ratios.size()));
      }
    }
  }

  {  // Figs. 52 and 53: Euclidean vs Mahalanobis consensus, success and time vs noise.
    auto f = Open(dir + "/fig52_53_distance.csv", "distance,sigma_m,thesis_success,correct_rate,median_ms");
    const std::vector<double> noise{0.1, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0};
    int done = 0;
    for (const char* distance : {"euclidean", "mahalanobis"}) {
      for (double s : noise) {
        AlignmentOptions o = ThesisRansac();
        if (std::string(distance) == "mahalanobis") o.distance = ConsensusDistance::kMahalanobis;
        double thesis = 0.0, ours = 0.0;
        std::vector<double> ms;
        for (int k = 0; k < kTrials; ++k) {
          std::mt19937_64 rng(seed++);
          const MapPair p = MakeMapPair(Maps(200, 1.0, s, true), rng);
          const Score sc = RansacOnly(p, 0.5, o, rng);
          thesis += sc.thesis;
          ours += sc.ours;
          ms.push_back(sc.ms);
        }
        std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
        f << distance << ',' << s << ',' << thesis / kTrials << ',' << ours / kTrials << ',' << ms[ms.size() / 2]
          << '\n';
        Progress("figs 52/53", ++done, 2 * static_cast<int>(noise.size()));
      }
    }
  }
}

}  // namespace mapmesh::lab
