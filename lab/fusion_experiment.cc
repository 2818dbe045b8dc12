#include "lab/fusion_experiment.h"

#include <Eigen/LU>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <tuple>

#include "common/merge/global_map.h"
#include "common/metrics/landmark_metrics.h"
#include "common/metrics/trajectory_metrics.h"

namespace mapmesh::lab {
namespace {

// Running sums behind an OverlapScore.
struct OverlapSum {
  int n = 0, consistent = 0;
  double nees = 0.0, det = 0.0, area = 0.0, se = 0.0;
  void Add(const Eigen::Vector2d& est, const Eigen::Matrix2d& cov, const Eigen::Vector2d& truth) {
    const double e = Nees(est, cov, truth);
    ++n;
    nees += e;
    consistent += e < kChi2Dof2P95;
    det += cov.determinant();
    area += EllipseArea(cov);
    se += (est - truth).squaredNorm();
  }
  OverlapScore Score() const {
    OverlapScore s;
    s.landmarks = n;
    if (n == 0) return s;
    s.nees = nees / n;
    s.consistent_ratio = static_cast<double>(consistent) / n;
    s.det = det / n;
    s.area_m2 = area / n;
    s.rmse_m = std::sqrt(se / n);
    return s;
  }
};

const SlamRunResult& Robot(const std::vector<SlamRunResult>& robots, RobotId id) {
  for (const SlamRunResult& r : robots) {
    if (r.robot == id) return r;
  }
  throw std::runtime_error("fusion experiment: no robot " + std::to_string(id) + " in the run");
}

std::vector<Eigen::Vector2d> InFrame(const std::vector<Eigen::Vector2d>& world, const Pose2& frame) {
  const Pose2 inv = frame.Inverse();
  std::vector<Eigen::Vector2d> out;
  out.reserve(world.size());
  for (const Eigen::Vector2d& p : world) out.push_back(inv.Apply(p));
  return out;
}

}  // namespace

namespace {

// Landmark ia of map a and ib of map b are one true landmark (known signatures).
bool IsTruePair(const LandmarkMap& a, const LandmarkMap& b, int ia, int ib) {
  const int s = a.landmarks[ia].signature;
  return s >= 0 && s == b.landmarks[ib].signature;
}

}  // namespace

FusionTrialResult RunFusionTrial(const std::vector<SlamRunResult>& robots, const FusionTrialOptions& o,
                                 std::mt19937_64& rng) {
  const SlamRunResult &ra = Robot(robots, o.a), &rb = Robot(robots, o.b);
  if (!ra.origin_truth || !rb.origin_truth || ra.landmark_truth.empty()) {
    throw std::runtime_error("fusion experiment: needs the robots' true frame origins and the landmark truth");
  }
  FusionTrialResult r;
  r.seed = ra.seed;
  r.robot_a = o.a;
  r.robot_b = o.b;
  const std::vector<Eigen::Vector2d> truth_a = InFrame(ra.landmark_truth, *ra.origin_truth);
  const std::vector<Eigen::Vector2d> truth_b = InFrame(rb.landmark_truth, *rb.origin_truth);
  const Pose2 truth = ra.origin_truth->Inverse() * *rb.origin_truth;  // b's frame into a's

  MapSource src;
  src.robot = o.b;
  src.map = rb.map;
  if (o.oracle_alignment) {
    r.verdict = AlignmentVerdict::kAccepted;
    src.to_own = truth;
  } else {
    const LandmarkMap ua = WithoutSignatures(ra.map), ub = WithoutSignatures(rb.map);
    // The candidates AlignMaps starts from (same draws: a copy of the generator), and those of
    // the thesis's own similarity metric (eq. 51-53).
    const auto true_ratio = [&](const AlignmentOptions& align) {
      std::mt19937_64 copy = rng;
      const std::vector<CandidatePair> cand = MatchTriangles(ua, ub, align, copy);
      int good = 0;
      for (const CandidatePair& c : cand) good += IsTruePair(ra.map, rb.map, c.a, c.b);
      return cand.empty() ? 0.0 : static_cast<double>(good) / cand.size();
    };
    r.similarity_true_ratio = true_ratio(o.align);
    AlignmentOptions thesis = o.align;
    thesis.matcher = TriangleMatcher::kThesisSimilarity;
    r.thesis_similarity_true_ratio = true_ratio(thesis);
    const AlignmentResult al = AlignMaps(ua, ub, o.align, rng);
    r.verdict = al.verdict;
    const TransformError e = CompareTransforms(al.transform, truth, Centroid(rb.map));
    r.translation_error_m = e.translation_m;
    r.rotation_error_deg = RadToDeg(e.rotation_rad);
    r.correct = al.accepted() && e.translation_m <= 1.0 && r.rotation_error_deg <= 2.0;
    {
      int shared = 0, found = 0;
      std::set<int> sig_b;
      for (const Landmark& l : rb.map.landmarks) sig_b.insert(l.signature);
      for (const Landmark& l : ra.map.landmarks) shared += l.signature >= 0 && sig_b.count(l.signature);
      for (const auto& [ia, ib] : al.inliers) found += IsTruePair(ra.map, rb.map, ia, ib);
      r.ransac_true_recall = shared > 0 ? static_cast<double>(found) / shared : 0.0;
    }
    if (!al.accepted()) return r;
    src.to_own = al.transform;
    src.to_own_cov = al.cov;
  }
  r.fused = true;

  std::set<int> sig_a, sig_b;
  for (const Landmark& l : ra.map.landmarks) sig_a.insert(l.signature);
  for (const Landmark& l : rb.map.landmarks) sig_b.insert(l.signature);
  int possible = 0;
  for (int s : sig_a) possible += s >= 0 && sig_b.count(s);

  const std::vector<MapSource> sources{src};
  for (std::size_t k = 0; k < o.methods.size(); ++k) {
    GlobalMapOptions go;
    go.method = o.methods[k];
    const GlobalMap g = BuildGlobalMap(ra.map, o.a, sources, go);
    OverlapSum merged;
    std::vector<std::pair<int, int>> predicted;
    OverlapSum own_a, own_b;
    for (std::size_t i = 0; i < g.map.size(); ++i) {
      const auto& org = g.origins[i];
      if (org.size() != 2 || org[0].robot != o.a || org[1].robot != o.b) continue;
      const Landmark* la = ra.map.Find(org[0].id);
      const Landmark* lb = rb.map.Find(org[1].id);
      if (!la || !lb || la->signature < 0) continue;
      predicted.emplace_back(la->signature, lb->signature);
      merged.Add(g.map.landmarks[i].mean, g.map.landmarks[i].cov, truth_a[la->signature]);
      if (o.keep_estimates) {
        const Eigen::Vector2d& t = truth_a[la->signature];
        if (k == 0) {
          const Landmark placed = TransformLandmark(*lb, src.to_own, src.to_own_cov);
          r.estimates.push_back({"robot_a", la->signature, t, la->mean, la->cov});
          r.estimates.push_back({"robot_b", la->signature, t, placed.mean, placed.cov});
        }
        r.estimates.push_back({std::string(ToString(o.methods[k])), la->signature, t, g.map.landmarks[i].mean,
                               g.map.landmarks[i].cov});
      }
      own_a.Add(la->mean, la->cov, truth_a[la->signature]);
      if (lb->signature >= 0) own_b.Add(lb->mean, lb->cov, truth_b[lb->signature]);
    }
    MethodScore m;
    m.method = o.methods[k];
    m.merged = merged.Score();
    const MapQuality q = EvaluateMap(g.map, truth_a, {});
    m.global_nees = q.nees_mean;
    m.global_consistent_ratio = q.consistent_ratio;
    m.global_rmse_m = q.rmse_m;
    m.global_landmarks = q.landmarks;
    r.methods.push_back(m);
    if (k == 0) {  // association and the single maps do not depend on the estimator
      r.association = ScoreAssociations(predicted, possible);
      r.a = own_a.Score();
      r.b = own_b.Score();
    }
  }
  return r;
}

namespace {

std::string Num(double v) {
  if (!std::isfinite(v)) return v > 0 ? "inf" : "nan";
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

std::string OverlapEstimatesCsv(const std::vector<OverlapEstimate>& estimates) {
  std::vector<const OverlapEstimate*> sorted;
  for (const OverlapEstimate& e : estimates) sorted.push_back(&e);
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const OverlapEstimate* x, const OverlapEstimate* y) { return x->signature < y->signature; });
  std::ostringstream s;
  s << "source,signature,truth_x,truth_y,x,y,cxx,cxy,cyy\n";
  for (const OverlapEstimate* e : sorted) {
    s << e->source << ',' << e->signature << ',' << Num(e->truth.x()) << ',' << Num(e->truth.y()) << ','
      << Num(e->mean.x()) << ',' << Num(e->mean.y()) << ',' << Num(e->cov(0, 0)) << ',' << Num(e->cov(0, 1)) << ','
      << Num(e->cov(1, 1)) << '\n';
  }
  return s.str();
}

std::vector<FusionTrialResult> RunFusionSweep(const ScenarioMaker& make, const FusionSweepOptions& o) {
  struct Job {
    double value;
    std::uint64_t seed;
  };
  std::vector<Job> jobs;
  for (double v : o.values) {
    for (int k = 0; k < o.seeds; ++k) jobs.push_back({v, o.first_seed + static_cast<std::uint64_t>(k)});
  }
  std::vector<std::pair<RobotId, RobotId>> pairs = o.pairs;
  if (pairs.empty()) pairs.emplace_back(o.trial.a, o.trial.b);
  std::vector<FusionTrialResult> out(jobs.size() * pairs.size());
  std::atomic<std::size_t> next{0};
  std::mutex mu;
  int done = 0;
  std::exception_ptr failure;
  auto worker = [&] {
    for (std::size_t i = next++; i < jobs.size(); i = next++) {
      try {
        const Scenario sc = make(jobs[i].value, jobs[i].seed);
        const std::vector<SlamRunResult> robots = RunSlam(sc, o.slam);
        for (std::size_t p = 0; p < pairs.size(); ++p) {
          std::mt19937_64 rng(jobs[i].seed * 7919 + 17);
          FusionTrialOptions trial = o.trial;
          std::tie(trial.a, trial.b) = pairs[p];
          FusionTrialResult& r = out[i * pairs.size() + p];
          r = RunFusionTrial(robots, trial, rng);
          r.value = jobs[i].value;
        }
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mu);
        if (!failure) failure = std::current_exception();
        next = jobs.size();
      }
      const std::lock_guard<std::mutex> lock(mu);
      ++done;
      if (o.progress) o.progress(done, static_cast<int>(jobs.size()));
    }
  };
  const int threads = o.threads > 0 ? o.threads : std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
  return out;
}

namespace {

// Landmark-weighted pooling of overlap scores.
struct Pool {
  double n = 0.0, nees = 0.0, consistent = 0.0, det = 0.0, area = 0.0, se = 0.0;
  void Add(const OverlapScore& s) {
    n += s.landmarks;
    nees += s.nees * s.landmarks;
    consistent += s.consistent_ratio * s.landmarks;
    det += s.det * s.landmarks;
    area += s.area_m2 * s.landmarks;
    se += s.rmse_m * s.rmse_m * s.landmarks;
  }
  OverlapScore Score() const {
    OverlapScore s;
    s.landmarks = static_cast<int>(n);
    if (n <= 0) {
      const double nan = std::numeric_limits<double>::quiet_NaN();
      s.nees = s.consistent_ratio = s.det = s.area_m2 = s.rmse_m = nan;
      return s;
    }
    s.nees = nees / n;
    s.consistent_ratio = consistent / n;
    s.det = det / n;
    s.area_m2 = area / n;
    s.rmse_m = std::sqrt(se / n);
    return s;
  }
};

}  // namespace

std::vector<FusionSweepRow> SummariseFusionSweep(const std::vector<FusionTrialResult>& trials,
                                                 const std::vector<FusionMethod>& methods) {
  std::map<std::tuple<double, RobotId, RobotId>, std::vector<const FusionTrialResult*>> by_value;
  for (const FusionTrialResult& t : trials) by_value[{t.value, t.robot_a, t.robot_b}].push_back(&t);
  std::vector<FusionSweepRow> out;
  for (const auto& [key, runs] : by_value) {
    const double value = std::get<0>(key);
    std::vector<const FusionTrialResult*> fused;
    for (const auto* t : runs) {
      if (t->fused) fused.push_back(t);
    }
    const double nf = static_cast<double>(fused.size());
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (std::size_t k = 0; k < methods.size(); ++k) {
      FusionSweepRow row;
      row.value = value;
      row.robot_a = std::get<1>(key);
      row.robot_b = std::get<2>(key);
      double sim_sum = 0.0, thesis_sum = 0.0, recall_sum = 0.0;
      for (const auto* t : runs) {
        sim_sum += t->similarity_true_ratio;
        thesis_sum += t->thesis_similarity_true_ratio;
        recall_sum += t->ransac_true_recall;
        row.correct_runs += t->correct;
      }
      row.similarity_true_ratio = runs.empty() ? nan : sim_sum / runs.size();
      row.ransac_true_recall = runs.empty() ? nan : recall_sum / runs.size();
      row.thesis_similarity_true_ratio = runs.empty() ? nan : thesis_sum / runs.size();
      row.method = methods[k];
      row.runs = static_cast<int>(runs.size());
      row.fused_runs = static_cast<int>(fused.size());
      Pool a, b, merged;
      double te = 0.0, re = 0.0, prec = 0.0, rec = 0.0, overlap = 0.0, gn = 0.0, gc = 0.0;
      for (const auto* t : fused) {
        te += t->translation_error_m;
        re += t->rotation_error_deg;
        prec += t->association.precision;
        rec += t->association.recall;
        overlap += t->a.landmarks;
        a.Add(t->a);
        b.Add(t->b);
        if (k < t->methods.size()) {
          merged.Add(t->methods[k].merged);
          gn += t->methods[k].global_nees;
          gc += t->methods[k].global_consistent_ratio;
        }
      }
      const auto mean = [&](double sum) { return nf > 0 ? sum / nf : nan; };
      row.translation_error_m = mean(te);
      row.rotation_error_deg = mean(re);
      row.association_precision = mean(prec);
      row.association_recall = mean(rec);
      row.overlap_landmarks = mean(overlap);
      row.a = a.Score();
      row.b = b.Score();
      row.merged = merged.Score();
      row.global_nees = mean(gn);
      row.global_consistent_ratio = mean(gc);
      out.push_back(row);
    }
  }
  return out;
}

std::string FusionSweepCsv(const std::string& parameter, const std::vector<FusionSweepRow>& rows) {
  std::ostringstream s;
  s << "parameter,value,method,runs,fused_runs,translation_error_m,rotation_error_deg,association_precision,"
       "association_recall,overlap_landmarks,nees_a,nees_b,consistent_a,consistent_b,det_a,det_b,area_a_m2,"
       "area_b_m2,nees_merged,consistent_merged,det_merged,area_merged_m2,rmse_merged_m,nees_global,"
       "consistent_global,robot_a,robot_b,similarity_true_ratio,ransac_true_recall,correct_runs,"
       "thesis_similarity_true_ratio\n";
  for (const FusionSweepRow& r : rows) {
    s << parameter << ',' << r.value << ',' << ToString(r.method) << ',' << r.runs << ',' << r.fused_runs << ','
      << Num(r.translation_error_m) << ',' << Num(r.rotation_error_deg) << ',' << Num(r.association_precision) << ','
      << Num(r.association_recall) << ',' << Num(r.overlap_landmarks) << ',' << Num(r.a.nees) << ',' << Num(r.b.nees)
      << ',' << Num(r.a.consistent_ratio) << ',' << Num(r.b.consistent_ratio) << ',' << Num(r.a.det) << ','
      << Num(r.b.det) << ',' << Num(r.a.area_m2) << ',' << Num(r.b.area_m2) << ',' << Num(r.merged.nees) << ','
      << Num(r.merged.consistent_ratio) << ',' << Num(r.merged.det) << ',' << Num(r.merged.area_m2) << ','
      << Num(r.merged.rmse_m) << ',' << Num(r.global_nees) << ',' << Num(r.global_consistent_ratio) << ',' << r.robot_a
      << ',' << r.robot_b << ',' << Num(r.similarity_true_ratio) << ',' << Num(r.ransac_true_recall) << ','
      << r.correct_runs << ',' << Num(r.thesis_similarity_true_ratio) << '\n';
  }
  return s.str();
}

std::vector<VictoriaPairResult> RunVictoriaPairs(const std::vector<SlamRunResult>& robots, const LandmarkMap& reference,
                                                 const FusionTrialOptions& o, std::mt19937_64& rng) {
  std::vector<VictoriaPairResult> out;
  const LandmarkMap ref = WithoutSignatures(reference);
  std::vector<Eigen::Vector2d> ref_points;
  for (const Landmark& l : ref.landmarks) ref_points.push_back(l.mean);
  // Each robot's frame in the reference's.
  std::map<RobotId, std::optional<AlignmentResult>> to_ref;
  for (const SlamRunResult& r : robots) {
    const AlignmentResult al = AlignMaps(ref, WithoutSignatures(r.map), o.align, rng);
    to_ref[r.robot] = al.accepted() ? std::optional<AlignmentResult>(al) : std::nullopt;
  }
  // NEES of an estimate in a robot's frame against the nearest reference landmark (within
  // 2 m after moving it into the reference frame), the reference's covariance added.
  auto ref_nees = [&](const Eigen::Vector2d& m, const Eigen::Matrix2d& c, const Pose2& t, double* out_nees) {
    const Eigen::Vector2d p = t.Apply(m);
    int best = -1;
    double best_d = 2.0;
    for (std::size_t i = 0; i < ref_points.size(); ++i) {
      const double d = (ref_points[i] - p).norm();
      if (d < best_d) {
        best_d = d;
        best = static_cast<int>(i);
      }
    }
    if (best < 0) return false;
    const Eigen::Matrix2d rot = t.Rotation();
    *out_nees = Nees(p, rot * c * rot.transpose() + ref.landmarks[best].cov, ref_points[best]);
    return true;
  };
  for (std::size_t i = 0; i < robots.size(); ++i) {
    for (std::size_t j = 0; j < robots.size(); ++j) {
      if (i == j) continue;
      const SlamRunResult &ra = robots[i], &rb = robots[j];
      if (ra.robot > rb.robot) continue;  // each unordered pair once, the lower id as a
      VictoriaPairResult p;
      p.a = ra.robot;
      p.b = rb.robot;
      const AlignmentResult al = AlignMaps(WithoutSignatures(ra.map), WithoutSignatures(rb.map), o.align, rng);
      p.verdict = al.verdict;
      if (!al.accepted() || !to_ref[ra.robot] || !to_ref[rb.robot]) {
        out.push_back(p);
        continue;
      }
      const Pose2 ta = to_ref[ra.robot]->transform, tb = to_ref[rb.robot]->transform;
      const std::vector<MapSource> sources{{rb.robot, 0, rb.map, al.transform, al.cov}};
      for (std::size_t k = 0; k < o.methods.size(); ++k) {
        GlobalMapOptions go;
        go.method = o.methods[k];
        const GlobalMap g = BuildGlobalMap(ra.map, ra.robot, sources, go);
        double sa = 0.0, sb = 0.0, sm = 0.0;
        int n = 0;
        for (std::size_t q = 0; q < g.map.size(); ++q) {
          const auto& org = g.origins[q];
          if (org.size() != 2) continue;
          const Landmark* la = ra.map.Find(org[0].id);
          const Landmark* lb = rb.map.Find(org[1].id);
          double ea = 0.0, eb = 0.0, em = 0.0;
          if (!la || !lb || !ref_nees(la->mean, la->cov, ta, &ea) || !ref_nees(lb->mean, lb->cov, tb, &eb) ||
              !ref_nees(g.map.landmarks[q].mean, g.map.landmarks[q].cov, ta, &em)) {
            continue;
          }
          sa += ea;
          sb += eb;
          sm += em;
          ++n;
        }
        if (k == 0) {
          p.overlap = n;
          p.nees_a = n ? sa / n : 0.0;
          p.nees_b = n ? sb / n : 0.0;
        }
        p.merged_nees.emplace_back(o.methods[k], n ? sm / n : 0.0);
      }
      out.push_back(p);
    }
  }
  return out;
}

std::string VictoriaPairsCsv(const std::vector<VictoriaPairResult>& pairs) {
  std::ostringstream s;
  s << "robot_a,robot_b,verdict,overlap_landmarks,nees_a,nees_b";
  if (!pairs.empty()) {
    for (const auto& pair : pairs) {
      if (pair.merged_nees.empty()) continue;
      for (const auto& [m, v] : pair.merged_nees) s << ",nees_merged_" << ToString(m);
      break;
    }
  }
  s << '\n';
  std::size_t columns = 0;
  for (const auto& p : pairs) columns = std::max(columns, p.merged_nees.size());
  for (const auto& p : pairs) {
    s << p.a << ',' << p.b << ',' << ToString(p.verdict) << ',' << p.overlap << ',' << Num(p.nees_a) << ','
      << Num(p.nees_b);
    for (std::size_t k = 0; k < columns; ++k)
      s << ',' << (k < p.merged_nees.size() ? Num(p.merged_nees[k].second) : "");
    s << '\n';
  }
  return s.str();
}

}  // namespace mapmesh::lab
