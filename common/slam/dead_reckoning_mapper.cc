#include "common/slam/dead_reckoning_mapper.h"

#include <cmath>

namespace mapmesh {

DeadReckoningMapper::DeadReckoningMapper(const DeadReckoningOptions& options) : options_(options) {}

void DeadReckoningMapper::Predict(const OdometryControl& u, double dt) {
  pose_ = MoveRobot(options_.motion, pose_, u, dt);
}

void DeadReckoningMapper::Observe(const std::vector<Observation>& obs, double /*stamp*/) {
  for (const Observation& o : obs) {
    if (o.kind != ObservationKind::kLandmark) continue;
    ++stats_.offered;
    if (!IsValidObservation(o)) {
      ++stats_.invalid;
      continue;
    }
    const double a = pose_.theta + o.bearing;
    const Eigen::Vector2d p(pose_.x + o.range * std::cos(a), pose_.y + o.range * std::sin(a));
    // Sensor noise projected into the map frame: radial sigma_r, tangential r * sigma_b.
    Eigen::Matrix2d rot;
    rot << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
    const Eigen::Matrix2d local = Eigen::Vector2d(options_.sigma_range_m * options_.sigma_range_m,
                                                  std::pow(o.range * options_.sigma_bearing_rad, 2))
                                      .asDiagonal();
    const Eigen::Matrix2d noise = rot * local * rot.transpose();

    std::size_t idx = tracks_.size();
    if (o.signature >= 0) {
      auto it = by_signature_.find(o.signature);
      if (it != by_signature_.end()) idx = it->second;
    } else {
      double best = options_.association_gate_m;
      for (std::size_t i = 0; i < tracks_.size(); ++i) {
        const double d = (tracks_[i].Mean() - p).norm();
        if (d < best) {
          best = d;
          idx = i;
        }
      }
    }
    if (idx == tracks_.size()) {
      ++stats_.initialised;
      Track t;
      t.signature = o.signature;
      t.id = o.signature >= 0 ? static_cast<std::uint32_t>(o.signature) : static_cast<std::uint32_t>(tracks_.size());
      tracks_.push_back(t);
      if (o.signature >= 0) by_signature_[o.signature] = idx;
    }
    Track& t = tracks_[idx];
    if (t.n > 0) ++stats_.associated;
    ++t.n;
    t.sum += p;
    t.sum_outer += p * p.transpose();
    t.sum_noise += noise;
  }
}

LandmarkMap DeadReckoningMapper::Map() const {
  LandmarkMap map;
  map.landmarks.reserve(tracks_.size());
  for (const Track& t : tracks_) {
    Landmark l;
    l.id = t.id;
    l.signature = t.signature;
    l.mean = t.Mean();
    // Covariance of the mean of n independent projections, plus the scatter of the
    // projections (which carries the pose drift between sightings).
    const double n = t.n;
    Eigen::Matrix2d cov = t.sum_noise / (n * n);
    if (t.n >= 2) {
      const Eigen::Matrix2d scatter = (t.sum_outer - n * l.mean * l.mean.transpose()) / (n - 1.0);
      cov += scatter / n;
    }
    l.cov = 0.5 * (cov + cov.transpose());
    map.landmarks.push_back(l);
  }
  return map;
}

}  // namespace mapmesh
