#include "common/merge/transform_search.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "common/geometry/rigid_fit.h"
#include "common/merge/alignment_fit.h"
#include "common/merge/point_grid.h"

namespace mapmesh {
namespace {

using alignment_detail::Conclude;
using alignment_detail::ForAlignment;
using alignment_detail::GatedPairs;
using alignment_detail::OneToOne;
using alignment_detail::Usable;
using alignment_detail::UsableLandmarks;

// The maps as alignment compares them, their usable landmarks, A's grid and the heuristic's
// per-landmark scales.
struct Search {
  Search(const LandmarkMap& a_in, const LandmarkMap& b_in, const AlignmentOptions& options)
      : o(options),
        a(ForAlignment(a_in, o.min_shape_sigma_m)),
        b(ForAlignment(b_in, o.min_shape_sigma_m)),
        ua(UsableLandmarks(a)),
        ub(UsableLandmarks(b)),
        grid(ua.points) {
    const double s0 = o.overlap.delta_sigma_m;
    for (double sb : ub.sigma) {
      const double s2 = s0 * s0 + 2.0 * sb * sb;
      reach.push_back(3.0 * std::sqrt(s2));
      half_inv_s2.push_back(0.5 / s2);
    }
  }

  // Delta(A, T(B)).
  double Delta(const Pose2& t) const {
    const PoseMap2 tm(t);
    double sum = 0.0;
    for (std::size_t j = 0; j < ub.points.size(); ++j) {
      const Eigen::Vector2d p = tm.Apply(ub.points[j]);
      const double r2 = reach[j] * reach[j];
      double best = r2;
      grid.Visit(p, reach[j], [&](int i) {
        best = std::min(best, (ua.points[i] - p).squaredNorm());
        return false;
      });
      if (best < r2) sum += std::exp(-best * half_inv_s2[j]);
    }
    return sum;
  }

  const AlignmentOptions& o;
  const LandmarkMap a, b;
  const Usable ua, ub;
  const PointGrid2 grid;
  std::vector<double> reach, half_inv_s2;
};

struct Hypothesis {
  Pose2 t;
  int support = -1;  // gated one-to-one pairs
  double cost = std::numeric_limits<double>::infinity();
  std::vector<std::pair<int, int>> pairs;  // sorted
  bool valid() const { return support >= 0; }
  bool BetterThan(const Hypothesis& o) const { return support > o.support || (support == o.support && cost < o.cost); }
};

// A hypothesis fitted to the landmarks it pairs: rounds of nearest-neighbour pairing within
// the heuristic's reach and a rigid least-squares fit, until the pairs stay the same (at most
// 10 rounds), then its gated pairs.
Hypothesis Fit(const Search& s, Pose2 t) {
  std::vector<std::pair<int, int>> last;
  for (int round = 0; round < 10; ++round) {
    std::vector<std::tuple<double, int, int>> scored;
    const PoseMap2 tm(t);
    for (std::size_t j = 0; j < s.ub.points.size(); ++j) {
      const Eigen::Vector2d p = tm.Apply(s.ub.points[j]);
      double best = std::numeric_limits<double>::infinity();
      int bi = -1;
      s.grid.Visit(p, s.reach[j], [&](int i) {
        const double d2 = (s.ua.points[i] - p).squaredNorm();
        if (d2 < best) {
          best = d2;
          bi = i;
        }
        return false;
      });
      if (bi >= 0) scored.emplace_back(best, bi, static_cast<int>(j));
    }
    std::vector<std::pair<int, int>> nn = OneToOne(std::move(scored));
    std::sort(nn.begin(), nn.end());
    if (nn.size() < 2 || nn == last) break;
    std::vector<Eigen::Vector2d> src, dst;
    for (const auto& [i, j] : nn) {
      src.push_back(s.ub.points[j]);
      dst.push_back(s.ua.points[i]);
    }
    const std::optional<Pose2> fit = FitRigid2D(src, dst);
    if (!fit) break;
    t = *fit;
    last = std::move(nn);
  }
  Hypothesis h;
  h.t = t;
  h.pairs = GatedPairs(s.a, s.ua, s.grid, s.b, s.ub, t, s.o, &h.cost);
  h.support = static_cast<int>(h.pairs.size());
  std::sort(h.pairs.begin(), h.pairs.end());
  return h;
}

// The best hypothesis and the best one different from it, as RANSAC keeps them: two that share
// same_alignment_overlap of the smaller one's pairs are one alignment.
class Tracker {
 public:
  explicit Tracker(const AlignmentOptions& o) : o_(o) {}

  void Offer(Hypothesis h) {
    const bool same_as_best = Same(h, best_);
    if (h.BetterThan(best_)) {
      const bool runner_same_as_h = Same(h, runner_);
      if (best_.valid() && !same_as_best && (runner_same_as_h || best_.BetterThan(runner_))) {
        runner_ = std::move(best_);
      } else if (runner_same_as_h) {
        runner_ = Hypothesis{};
      }
      best_ = std::move(h);
    } else if (!same_as_best && h.BetterThan(runner_)) {
      runner_ = std::move(h);
    }
  }
  const Hypothesis& best() const { return best_; }
  const Hypothesis& runner() const { return runner_; }

 private:
  bool Same(const Hypothesis& x, const Hypothesis& y) const {
    if (!x.valid() || !y.valid()) return false;
    std::size_t shared = 0;
    for (auto i = x.pairs.begin(), k = y.pairs.begin(); i != x.pairs.end() && k != y.pairs.end();) {
      if (*i < *k) {
        ++i;
      } else if (*k < *i) {
        ++k;
      } else {
        ++shared;
        ++i;
        ++k;
      }
    }
    return static_cast<double>(shared) >=
           o_.same_alignment_overlap * static_cast<double>(std::min(x.pairs.size(), y.pairs.size()));
  }

  const AlignmentOptions& o_;
  Hypothesis best_, runner_;
};

// From the tracker's best: the refinement and the acceptance tests.
AlignmentResult Finish(const LandmarkMap& a_in, const LandmarkMap& b_in, const Search& s, const Tracker& tracker,
                       AlignmentResult r) {
  r.best_support = std::max(0, tracker.best().support);
  r.runner_up_support = std::max(0, tracker.runner().support);
  if (tracker.best().support < 2) {
    r.verdict = AlignmentVerdict::kTooFewInliers;
    return r;
  }
  Conclude(a_in, b_in, s.a, s.b, tracker.best().t, tracker.best().pairs, s.o, s.o.guided_matching, r);
  return r;
}

// Each point's direction to its nearest neighbour among the points (0 for a point alone).
std::vector<double> NearestDirections(const std::vector<Eigen::Vector2d>& points) {
  std::vector<double> out(points.size(), 0.0);
  if (points.size() < 2) return out;
  Eigen::Vector2d lo = points[0], hi = points[0];
  for (const Eigen::Vector2d& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double extent = (hi - lo).norm();
  const Eigen::Vector2d size = (hi - lo).cwiseMax(Eigen::Vector2d::Constant(1e-9));
  const double start = std::max(1e-6, std::sqrt(size.x() * size.y() / static_cast<double>(points.size())));
  const PointGrid2 grid(points);
  for (std::size_t k = 0; k < points.size(); ++k) {
    int nearest = -1;
    for (double r = start;; r *= 2.0) {
      double best = std::numeric_limits<double>::infinity();
      grid.Visit(points[k], r, [&](int i) {
        const double d2 = (points[i] - points[k]).squaredNorm();
        if (static_cast<std::size_t>(i) != k && d2 < best) {
          best = d2;
          nearest = i;
        }
        return false;
      });
      if (nearest >= 0 || r > 2.0 * extent + 1.0) break;
    }
    if (nearest >= 0) {
      const Eigen::Vector2d d = points[nearest] - points[k];
      out[k] = std::atan2(d.y(), d.x());
    }
  }
  return out;
}

AlignmentResult Counted(const Search& s, AlignmentResult r) {
  r.usable_a = static_cast<int>(s.ua.points.size());
  r.usable_b = static_cast<int>(s.ub.points.size());
  if (r.usable_a < 3 || r.usable_b < 3) r.verdict = AlignmentVerdict::kTooFewLandmarks;
  return r;
}

}  // namespace

double OverlapHeuristic(const LandmarkMap& a, const LandmarkMap& b, const Pose2& t, const AlignmentOptions& o) {
  return Search(a, b, o).Delta(t);
}

AlignmentResult RandomWalkAlign(const LandmarkMap& a_in, const LandmarkMap& b_in,
                                const std::vector<CandidatePair>& cand, const AlignmentOptions& o,
                                std::mt19937_64& rng) {
  const Search s(a_in, b_in, o);
  AlignmentResult r;
  r.candidates = static_cast<int>(cand.size());
  r = Counted(s, r);
  if (r.usable_a < 3 || r.usable_b < 3) return r;
  if (cand.empty()) {
    r.verdict = AlignmentVerdict::kNoCandidates;
    return r;
  }
  const RandomWalkOptions& w = o.arw;
  const int per_restart = std::max(1, w.steps_per_restart);
  const int restarts = std::max(1, w.steps / per_restart);
  const Eigen::Vector3d init_var(w.init_sigma_m * w.init_sigma_m, w.init_sigma_m * w.init_sigma_m,
                                 w.init_sigma_rad * w.init_sigma_rad);
  const Eigen::Vector3d min_var(w.min_sigma_m * w.min_sigma_m, w.min_sigma_m * w.min_sigma_m,
                                w.min_sigma_rad * w.min_sigma_rad);
  const Eigen::Vector3d max_var = w.max_sigma_scale * w.max_sigma_scale * init_var;
  std::uniform_int_distribution<std::size_t> pick(0, cand.size() - 1);
  std::uniform_real_distribution<double> angle(-M_PI, M_PI), unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  Tracker tracker(o);
  int steps = 0;
  for (int restart = 0; restart < restarts; ++restart) {
    // Pin a candidate pair at a random rotation: the sample (x, y, theta) lays b at (x, y),
    // B turned by theta about b.
    const CandidatePair& c = cand[pick(rng)];
    const Eigen::Vector2d pivot = s.b.landmarks[c.b].mean;
    auto pose = [&](const Eigen::Vector3d& v) {
      const Eigen::Vector2d t = v.head<2>() - Eigen::Rotation2Dd(v(2)).toRotationMatrix() * pivot;
      return Pose2{t.x(), t.y(), v(2)};
    };
    Eigen::Vector3d sample(s.a.landmarks[c.a].mean.x(), s.a.landmarks[c.a].mean.y(), angle(rng));
    double score = s.Delta(pose(sample));
    Eigen::Vector3d best = sample;
    double best_score = score;
    std::deque<Eigen::Vector3d> accepted;  // the last M accepted steps
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    Eigen::Matrix3d chol = init_var.cwiseSqrt().asDiagonal();
    const int budget = restart + 1 == restarts ? w.steps - steps : per_restart;
    for (int k = 0; k < budget; ++k, ++steps) {
      const Eigen::Vector3d step = mean + chol * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
      Eigen::Vector3d next = sample + step;
      next(2) = WrapAngle(next(2));
      const double next_score = s.Delta(pose(next));
      if (!(next_score > score) && !(unit(rng) < std::exp((next_score - score) / w.temperature))) continue;
      sample = next;
      score = next_score;
      if (score > best_score) {
        best_score = score;
        best = sample;
      }
      accepted.push_back(step);
      if (static_cast<int>(accepted.size()) > w.memory) accepted.pop_front();
      if (static_cast<int>(accepted.size()) < std::max(2, w.memory)) continue;
      // The proposal adapts to the last M accepted steps: their mean and covariance, plus a
      // floor, each standard deviation within max_sigma_scale of the initial one.
      mean.setZero();
      for (const Eigen::Vector3d& v : accepted) mean += v;
      mean /= static_cast<double>(accepted.size());
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (const Eigen::Vector3d& v : accepted) cov += (v - mean) * (v - mean).transpose();
      cov /= static_cast<double>(accepted.size() - 1);
      cov += min_var.asDiagonal();
      Eigen::Vector3d scale = Eigen::Vector3d::Ones();
      for (int i = 0; i < 3; ++i) {
        if (cov(i, i) > max_var(i)) scale(i) = std::sqrt(max_var(i) / cov(i, i));
      }
      cov = (scale.asDiagonal() * cov * scale.asDiagonal()).eval();
      for (int i = 0; i < 3; ++i) mean(i) = std::clamp(mean(i), -std::sqrt(max_var(i)), std::sqrt(max_var(i)));
      const Eigen::LLT<Eigen::Matrix3d> llt(cov);
      if (llt.info() == Eigen::Success) chol = llt.matrixL();
    }
    tracker.Offer(Fit(s, pose(best)));
  }
  r.iterations = steps;
  return Finish(a_in, b_in, s, tracker, r);
}

AlignmentResult TranslationSearchAlign(const LandmarkMap& a_in, const LandmarkMap& b_in, const AlignmentOptions& o) {
  const Search s(a_in, b_in, o);
  AlignmentResult r = Counted(s, AlignmentResult{});
  if (r.usable_a < 3 || r.usable_b < 3) return r;
  const TranslationSearchOptions& its = o.its;
  const std::vector<double> dir_a = NearestDirections(s.ua.points), dir_b = NearestDirections(s.ub.points);
  // A's directions sorted, for the landmarks within an angle of one.
  std::vector<std::pair<double, int>> by_dir;
  for (std::size_t i = 0; i < dir_a.size(); ++i) by_dir.emplace_back(dir_a[i], static_cast<int>(i));
  std::sort(by_dir.begin(), by_dir.end());
  auto within_angle = [&](double phi, double eps, auto&& f) {
    // [phi - eps, phi + eps], wrapped: up to two ranges of the sorted directions.
    const double lo = phi - eps, hi = phi + eps;
    auto visit = [&](double x0, double x1) {
      auto it = std::lower_bound(by_dir.begin(), by_dir.end(), std::pair<double, int>(x0, -1));
      for (; it != by_dir.end() && it->first <= x1; ++it) f(it->second);
    };
    if (eps >= M_PI) {
      visit(-M_PI - 1.0, M_PI + 1.0);
    } else {
      visit(std::max(lo, -M_PI - 1.0), std::min(hi, M_PI + 1.0));
      if (lo < -M_PI) visit(lo + 2.0 * M_PI, M_PI + 1.0);
      if (hi > M_PI) visit(-M_PI - 1.0, hi - 2.0 * M_PI);
    }
  };

  // The rotation grid: the step turns B's farthest landmark (from its centroid) by at most the gate.
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : s.ub.points) centroid += p;
  centroid /= static_cast<double>(s.ub.points.size());
  double radius = 0.0;
  for (const Eigen::Vector2d& p : s.ub.points) radius = std::max(radius, (p - centroid).norm());
  int rotations = std::max(1, its.rotations);
  if (radius > 0 && its.gate_m > 0) {
    rotations = std::max(rotations, static_cast<int>(std::ceil(2.0 * M_PI * radius / its.gate_m)));
  }
  rotations = std::min(rotations, std::max(1, its.max_rotations));

  struct Cell {
    int n = 0;
    Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  };
  auto key = [](std::int64_t x, std::int64_t y) { return (x << 32) ^ (y & 0xffffffff); };
  std::vector<std::pair<double, Pose2>> found;  // (Delta, transform)
  int iterations = 0;
  for (int k = 0; k < rotations; ++k) {
    const double theta = -M_PI + 2.0 * M_PI * k / rotations;
    const Eigen::Matrix2d rot = Eigen::Rotation2Dd(theta).toRotationMatrix();
    std::vector<Eigen::Vector2d> turned(s.ub.points.size());
    for (std::size_t j = 0; j < turned.size(); ++j) turned[j] = rot * s.ub.points[j];
    // Translation votes of the direction-compatible pairs.
    std::unordered_map<std::int64_t, Cell> cells;
    for (std::size_t j = 0; j < turned.size(); ++j) {
      within_angle(WrapAngle(dir_b[j] + theta), its.start_epsilon_rad, [&](int i) {
        const Eigen::Vector2d v = s.ua.points[i] - turned[j];
        Cell& c = cells[key(static_cast<std::int64_t>(std::floor(v.x() / its.vote_cell_m)),
                            static_cast<std::int64_t>(std::floor(v.y() / its.vote_cell_m)))];
        ++c.n;
        c.sum += v;
      });
    }
    // The best 3 x 3 blocks of cells, apart, centred on cells with more than one vote (all
    // cells when none has).
    int most = 0;
    for (const auto& [kk, c] : cells) most = std::max(most, c.n);
    const int centre_votes = std::min(2, most);
    std::vector<std::tuple<int, std::int64_t, std::int64_t>> blocks;  // (votes, cx, cy)
    for (const auto& [kk, c] : cells) {
      if (c.n < centre_votes) continue;
      const Eigen::Vector2d m = c.sum / c.n;
      const std::int64_t cx = static_cast<std::int64_t>(std::floor(m.x() / its.vote_cell_m));
      const std::int64_t cy = static_cast<std::int64_t>(std::floor(m.y() / its.vote_cell_m));
      int n = 0;
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          auto it = cells.find(key(cx + dx, cy + dy));
          if (it != cells.end()) n += it->second.n;
        }
      }
      blocks.emplace_back(n, cx, cy);
    }
    std::sort(blocks.begin(), blocks.end(), [](const auto& x, const auto& y) { return x > y; });
    std::vector<std::pair<std::int64_t, std::int64_t>> seeds;
    for (const auto& [n, cx, cy] : blocks) {
      if (static_cast<int>(seeds.size()) >= its.seeds_per_rotation) break;
      bool apart = true;
      for (const auto& [sx, sy] : seeds) apart = apart && std::max(std::abs(sx - cx), std::abs(sy - cy)) >= 3;
      if (apart) seeds.emplace_back(cx, cy);
    }
    for (const auto& [cx, cy] : seeds) {
      Cell block;
      for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
          auto it = cells.find(key(cx + dx, cy + dy));
          if (it == cells.end()) continue;
          block.n += it->second.n;
          block.sum += it->second.sum;
        }
      }
      if (block.n == 0) continue;
      // Table 4: pair each of B's landmarks with the closest compatible one of A's, move B by the
      // pairs' mean difference, shrink epsilon.
      Eigen::Vector2d t = block.sum / block.n;
      double eps = its.start_epsilon_rad;
      for (int it = 0; it < its.max_iterations; ++it) {
        ++iterations;
        Eigen::Vector2d sum = Eigen::Vector2d::Zero();
        int n = 0;
        for (std::size_t j = 0; j < turned.size(); ++j) {
          const Eigen::Vector2d p = turned[j] + t;
          double best = std::numeric_limits<double>::infinity();
          int bi = -1;
          s.grid.Visit(p, its.gate_m, [&](int i) {
            const double d2 = (s.ua.points[i] - p).squaredNorm();
            if (d2 < best && std::abs(WrapAngle(dir_a[i] - dir_b[j] - theta)) < eps) {
              best = d2;
              bi = i;
            }
            return false;
          });
          if (bi < 0) continue;
          sum += s.ua.points[bi] - turned[j];
          ++n;
        }
        if (n == 0) break;
        const Eigen::Vector2d next = sum / n;
        const double moved = (next - t).norm();
        t = next;
        eps = std::max(its.min_epsilon_rad, eps * its.epsilon_shrink);
        if (moved < its.converged_m) break;
      }
      const Pose2 pose{t.x(), t.y(), theta};
      found.emplace_back(s.Delta(pose), pose);
    }
  }
  // The best by Delta, fitted and compared.
  std::sort(found.begin(), found.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
  Tracker tracker(o);
  for (int k = 0; k < std::min<int>(its.hypotheses, static_cast<int>(found.size())); ++k) {
    tracker.Offer(Fit(s, found[k].second));
  }
  r.iterations = iterations;
  return Finish(a_in, b_in, s, tracker, r);
}

}  // namespace mapmesh
