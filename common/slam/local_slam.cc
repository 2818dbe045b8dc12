#include "common/slam/local_slam.h"

#include <Eigen/LU>
#include <algorithm>
#include <limits>
#include <unordered_set>

#include "common/check.h"
#include "common/geometry/covariance2.h"
#include "common/geometry/spatial.h"
#include "common/slam/ekf_slam.h"
#include "common/slam/iekf_slam.h"
#include "common/slam/observation_model.h"

namespace mapmesh {

LocalSlam::LocalSlam(const FilterNoise& noise, const LocalSlamOptions& options) : noise_(noise), options_(options) {
  MAPMESH_CHECK(options.filter == SlamMethod::kEkf || options.filter == SlamMethod::kCekf ||
                    options.filter == SlamMethod::kIekf,
                "LocalSlam runs the ekf, the cekf or the iekf");
  MAPMESH_CHECK(options.association.method != AssociationMethod::kAuto, "resolve the association method (ForSensor)");
  if (options.filter == SlamMethod::kEkf) {
    filter_ = std::make_unique<EkfSlam>(noise, options.ekf);
  } else if (options.filter == SlamMethod::kIekf) {
    filter_ = std::make_unique<IekfSlam>(noise);
  } else {
    filter_ = std::make_unique<CekfSlam>(noise, options.cekf, options.ekf);
  }
}

void LocalSlam::Predict(const OdometryControl& u, double dt) { filter_->Predict(u, dt); }

bool LocalSlam::AddOrHold(LandmarkId id, std::int32_t signature, const Eigen::Vector2d& z, double stamp) {
  if (!options_.tentative) {
    filter_->Add(id, z);
    ++stats_.initialised;
    return true;
  }
  const Eigen::Vector2d p = InverseRangeBearing(filter_->robot(), z);
  for (auto it = tentatives_.begin(); it != tentatives_.end(); ++it) {
    const bool same = signature >= 0 ? it->signature == signature
                                     : it->signature < 0 && (it->position - p).norm() < options_.tentative_gate_m;
    if (same) {
      tentatives_.erase(it);
      filter_->Add(id, z);
      ++stats_.initialised;
      return true;
    }
  }
  tentatives_.push_back({p, signature, stamp});
  ++stats_.tentative;
  return false;
}

void LocalSlam::Observe(const std::vector<Observation>& obs, double stamp) {
  // Forget tentative landmarks that were not seen again in time.
  std::erase_if(tentatives_, [&](const Tentative& t) { return stamp - t.stamp > options_.tentative_timeout_s; });

  decisions_.assign(obs.size(), Decision{});
  std::vector<Eigen::Vector2d> z;
  std::vector<std::int32_t> sig;
  std::vector<std::size_t> source;  // index in obs of each entry of z
  for (std::size_t k = 0; k < obs.size(); ++k) {
    const Observation& o = obs[k];
    if (o.kind != ObservationKind::kLandmark) {
      decisions_[k].landmark = kNotLandmark;
      continue;
    }
    ++stats_.offered;
    if (!IsValidObservation(o)) {
      ++stats_.invalid;
      continue;
    }
    if (o.range < options_.min_range_m || (options_.max_range_m > 0.0 && o.range > options_.max_range_m)) {
      ++stats_.out_of_range;
      continue;
    }
    z.emplace_back(o.range, o.bearing);
    sig.push_back(o.signature);
    source.push_back(k);
  }
  if (z.empty()) return;

  const AssociationProblem problem = MakeAssociationProblem(*filter_, noise_.obs_cov, z, sig);
  const AssociationResult a = Associate(problem, options_.association);
  stats_.rejected_gate += a.rejected_by_gate;
  stats_.ambiguous += a.ambiguous;
  stats_.unidentified += a.unidentified;

  std::vector<std::pair<LandmarkId, Eigen::Vector2d>> updates;
  std::unordered_set<LandmarkId> updated;
  std::vector<std::size_t> fresh;
  for (std::size_t i = 0; i < z.size(); ++i) {
    if (a.match[i] >= 0) {
      const LandmarkId id = problem.candidates[a.match[i]];
      if (updated.insert(id).second) {
        updates.push_back({id, z[i]});
        decisions_[source[i]].landmark = id;
      } else {
        ++stats_.ambiguous;  // a second observation of the same landmark in one scan
      }
    } else if (a.match[i] == AssociationResult::kNew) {
      fresh.push_back(i);
    }
  }
  if (!updates.empty()) {
    if (filter_->Update(updates)) {
      stats_.associated += updates.size();
    } else {
      ++stats_.failed_updates;
      for (Decision& d : decisions_) {
        if (d.landmark >= 0) d.landmark = kDropped;
      }
    }
  }
  // New landmarks, from the updated pose.
  std::vector<Eigen::Vector2d> placed;
  for (std::size_t i : fresh) {
    if (options_.association.method == AssociationMethod::kKnown) {
      const auto id = static_cast<LandmarkId>(sig[i]);
      if (filter_->Has(id) || updated.count(id)) {
        ++stats_.ambiguous;  // a landmark outside the active region, or seen twice
        continue;
      }
      updated.insert(id);
      const bool added = AddOrHold(id, sig[i], z[i], stamp);
      decisions_[source[i]] = {added ? static_cast<std::int64_t>(id) : kHeld, added};
      continue;
    }
    const Eigen::Vector2d p = InverseRangeBearing(filter_->robot(), z[i]);
    const bool duplicate = std::any_of(placed.begin(), placed.end(), [&](const Eigen::Vector2d& q) {
      return (q - p).norm() < options_.new_landmark_separation_m;
    });
    if (duplicate) {
      ++stats_.ambiguous;
      continue;
    }
    placed.push_back(p);
    const bool added = AddOrHold(next_id_, -1, z[i], stamp);
    decisions_[source[i]] = {added ? static_cast<std::int64_t>(next_id_) : kHeld, added};
    if (added) ++next_id_;
  }
}

double ShapeSigma(const LandmarkMap& map, const LandmarkFilter& filter) {
  return ShapeSigma(map, [&](std::size_t i, std::size_t j) {
    return filter.CrossCov(map.landmarks[i].id, map.landmarks[j].id);
  });
}

double ShapeSigma(const LandmarkMap& map, const std::function<Eigen::Matrix2d(std::size_t, std::size_t)>& cross_cov) {
  const std::size_t n = map.size();
  if (n < 2) return 0.0;
  std::vector<Eigen::Vector2d> points;
  points.reserve(n);
  for (const Landmark& l : map.landmarks) points.push_back(l.mean);
  // Nearest neighbours: the nearest-neighbour graph is a subgraph of the Delaunay graph.
  std::vector<int> nearest(n, -1);
  std::vector<double> dist(n, std::numeric_limits<double>::infinity());
  auto consider = [&](int i, int j) {
    const double d = (points[i] - points[j]).squaredNorm();
    if (d < dist[i]) {
      dist[i] = d;
      nearest[i] = j;
    }
  };
  const auto triangles = DelaunayTriangles(points);
  for (const auto& t : triangles) {
    for (int k = 0; k < 3; ++k) {
      consider(t[k], t[(k + 1) % 3]);
      consider(t[(k + 1) % 3], t[k]);
    }
  }
  if (triangles.empty()) {  // collinear or two points: every pair
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = 0; j < n; ++j) {
        if (i != j) consider(static_cast<int>(i), static_cast<int>(j));
      }
    }
  }
  std::vector<double> s;
  s.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (nearest[i] < 0) continue;
    const Landmark &a = map.landmarks[i], &b = map.landmarks[nearest[i]];
    const Eigen::Matrix2d c = cross_cov(i, static_cast<std::size_t>(nearest[i]));
    const Eigen::Matrix2d d = a.cov + b.cov - c - c.transpose();
    s.push_back(std::sqrt(std::max(0.0, LargestEigenvalue(d)) / 2.0));
  }
  if (s.empty()) return 0.0;
  const std::size_t k = std::min(s.size() - 1, static_cast<std::size_t>(0.9 * static_cast<double>(s.size())));
  std::nth_element(s.begin(), s.begin() + static_cast<long>(k), s.end());
  return s[k];
}

LandmarkMap LocalSlam::Map() const {
  LandmarkMap m = filter_->Map();
  m.shape_sigma_m = ShapeSigma(m, *filter_);
  if (options_.association.method == AssociationMethod::kKnown) {
    for (Landmark& l : m.landmarks) l.signature = static_cast<std::int32_t>(l.id);
  }
  return m;
}

}  // namespace mapmesh
