#include "lab/victoria_world.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <sstream>
#include <stdexcept>

namespace mapmesh::lab {
namespace {

// Landmarks within `reach` of any point of a path (indices into landmarks).
std::set<int> Neighbourhood(const std::vector<Eigen::Vector2d>& landmarks, const std::vector<Eigen::Vector2d>& path,
                            double reach) {
  std::set<int> near;
  for (int i = 0; i < static_cast<int>(landmarks.size()); ++i) {
    for (const Eigen::Vector2d& p : path) {
      if ((landmarks[i] - p).norm() <= reach) {
        near.insert(i);
        break;
      }
    }
  }
  return near;
}

int SharedCount(const std::set<int>& a, const std::set<int>& b) {
  int n = 0;
  for (int i : a) n += static_cast<int>(b.count(i));
  return n;
}

// Points along a path no closer than spacing to the previous kept point (the last always kept).
std::vector<Eigen::Vector2d> Thin(const std::vector<Eigen::Vector2d>& path, double spacing) {
  std::vector<Eigen::Vector2d> out;
  for (const Eigen::Vector2d& p : path) {
    if (out.empty() || (p - out.back()).norm() >= spacing) out.push_back(p);
  }
  if (!path.empty() && (path.back() - out.back()).norm() > 1e-9) out.push_back(path.back());
  return out;
}

double Length(const std::vector<Eigen::Vector2d>& path) {
  double l = 0.0;
  for (std::size_t i = 1; i < path.size(); ++i) l += (path[i] - path[i - 1]).norm();
  return l;
}

std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", v);
  return buf;
}

}  // namespace

VictoriaWorld DeriveVictoriaWorld(const SlamRunResult& whole, const VictoriaWorldOptions& o) {
  if (o.segments < o.robots || o.robots < 2)
    throw std::invalid_argument("victoria world: need 2 <= robots <= segments");
  if (whole.poses.size() < 2) throw std::invalid_argument("victoria world: the whole run has no trajectory");
  VictoriaWorld w;
  for (const Landmark& l : whole.map.landmarks) w.landmarks.push_back(l.mean);

  // Disjoint spans of equal duration.
  const double t0 = whole.poses.front().t, t1 = whole.poses.back().t;
  std::vector<std::vector<Eigen::Vector2d>> spans(o.segments);
  for (const auto& p : whole.poses) {
    const int k = std::min(o.segments - 1, static_cast<int>((p.t - t0) / (t1 - t0) * o.segments));
    spans[k].push_back({p.pose.x, p.pose.y});
  }
  std::vector<std::set<int>> near(o.segments);
  std::vector<bool> usable(o.segments);
  for (int k = 0; k < o.segments; ++k) {
    spans[k] = Thin(spans[k], o.waypoint_spacing_m);
    near[k] = Neighbourhood(w.landmarks, spans[k], o.visible_m);
    usable[k] = spans[k].size() >= 2 && Length(spans[k]) >= o.min_segment_m;
  }

  // Every subset of `robots` spans (at most C(segments, robots)); the best by the smallest
  // pairwise overlap, then by the total.
  std::vector<int> best;
  int best_min = -1, best_total = -1;
  std::vector<bool> pick(o.segments, false);
  std::fill(pick.begin(), pick.begin() + o.robots, true);
  do {
    std::vector<int> s;
    for (int k = 0; k < o.segments; ++k)
      if (pick[k]) s.push_back(k);
    if (!std::all_of(s.begin(), s.end(), [&](int k) { return usable[k]; })) continue;
    int lo = 1 << 30, total = 0;
    for (std::size_t i = 0; i < s.size(); ++i)
      for (std::size_t j = i + 1; j < s.size(); ++j) {
        const int n = SharedCount(near[s[i]], near[s[j]]);
        lo = std::min(lo, n);
        total += n;
      }
    if (lo > best_min || (lo == best_min && total > best_total)) {
      best = s;
      best_min = lo;
      best_total = total;
    }
  } while (std::prev_permutation(pick.begin(), pick.end()));
  if (best.empty()) throw std::invalid_argument("victoria world: too few spans long enough to drive");

  w.kept = best;
  for (int k : best) {
    w.paths.push_back(spans[k]);
    w.length_m.push_back(Length(spans[k]));
    w.neighbourhood.push_back(static_cast<int>(near[k].size()));
  }
  w.shared.assign(best.size(), std::vector<int>(best.size(), 0));
  for (std::size_t i = 0; i < best.size(); ++i)
    for (std::size_t j = 0; j < best.size(); ++j)
      w.shared[i][j] = i == j ? w.neighbourhood[i] : SharedCount(near[best[i]], near[best[j]]);
  return w;
}

std::string VictoriaLandmarksCsv(const VictoriaWorld& w) {
  std::ostringstream out;
  out << "# Victoria Park trees: the whole run's SLAM map (mapmesh-lab victoria-world), in its start frame\n";
  for (const Eigen::Vector2d& l : w.landmarks) out << Num(l.x()) << ',' << Num(l.y()) << '\n';
  return out.str();
}

std::string VictoriaScenarioYaml(const VictoriaWorld& w, const std::string& landmarks_csv) {
  double longest = 0.0;
  for (double l : w.length_m) longest = std::max(longest, l);
  constexpr double kSpeed = 2.0;  // m/s; the car averaged 2.6 m/s
  std::ostringstream y;
  y << "# Simulated Victoria Park (thesis 4.2, 5.3-5.4): robots driven by the thesis's motion and sensor\n"
       "# models over the park's trees, with ground truth. Made by `mapmesh-lab victoria-world` from the\n"
       "# dataset (docs/THESIS.md): the trees are the whole run's own SLAM map, the paths "
    << w.kept.size() << " of "
    << "the run's\n# disjoint time spans (spans";
  for (int k : w.kept) y << ' ' << k + 1;
  y << ", of 8), kept for the landmarks they share pairwise (smallest: ";
  int lo = 1 << 30;
  for (std::size_t i = 0; i < w.shared.size(); ++i)
    for (std::size_t j = i + 1; j < w.shared.size(); ++j) lo = std::min(lo, w.shared[i][j]);
  y << lo << ").\n# Do not edit by hand: regenerate with mapmesh-lab victoria-world.\n";
  y << "version: 1\nname: victoria_sim\nseed: 1\n";
  y << "duration_s: " << std::ceil(longest / kSpeed + 20.0) << '\n';
  y << "world:\n  landmarks:\n    csv: " << landmarks_csv << '\n';
  y << "robots:\n  defaults:\n    preset: thesis\n"
       "    motion: {speed_mps: "
    << kSpeed
    << ", max_turn_rate_dps: 45, waypoint_radius_m: 2, steering: smooth}\n"
       "    sensor: {max_range_m: 12, signatures: true}\n"
       "  list:\n";
  for (std::size_t r = 0; r < w.paths.size(); ++r) {
    const auto& p = w.paths[r];
    const Eigen::Vector2d d = p[1] - p[0];
    y << "    - id: " << r + 1 << "  # span " << w.kept[r] + 1 << ", " << Num(w.length_m[r]) << " m\n";
    y << "      start: [" << Num(p[0].x()) << ", " << Num(p[0].y()) << ", "
      << Num(std::atan2(d.y(), d.x()) * 180.0 / M_PI) << "]\n";
    y << "      path:\n        type: waypoints\n        loop: false\n        points: [";
    for (std::size_t i = 1; i < p.size(); ++i)
      y << (i > 1 ? ", " : "") << '[' << Num(p[i].x()) << ", " << Num(p[i].y()) << ']';
    y << "]\n";
  }
  y << "radio:\n  range_m: 1000\n";
  return y.str();
}

}  // namespace mapmesh::lab
