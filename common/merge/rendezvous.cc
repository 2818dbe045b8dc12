#include "common/merge/rendezvous.h"

#include <cmath>

namespace mapmesh {

std::optional<RendezvousResult> RendezvousAlign(const RendezvousInput& in) {
  const double values[] = {in.pose1.x,     in.pose1.y, in.pose1.theta, in.pose2.x, in.pose2.y,
                           in.pose2.theta, in.range12, in.bearing12,   in.range21, in.bearing21};
  for (double v : values) {
    if (!std::isfinite(v)) return std::nullopt;
  }
  if (!(in.sigma_range1 > 0 && in.sigma_range2 > 0) || !in.cov1.allFinite() || !in.cov2.allFinite())
    return std::nullopt;
  RendezvousResult r;
  // Eq. 40: inverse-variance mean of the two ranges.
  const double w1 = 1.0 / (in.sigma_range1 * in.sigma_range1), w2 = 1.0 / (in.sigma_range2 * in.sigma_range2);
  r.range = (w1 * in.range12 + w2 * in.range21) / (w1 + w2);
  r.range_disagreement = std::abs(in.range12 - in.range21) /
                         std::sqrt(in.sigma_range1 * in.sigma_range1 + in.sigma_range2 * in.sigma_range2);
  // Eq. 42-44: robot 2 in robot 1's frame.
  const double c = std::cos(in.bearing12), s = std::sin(in.bearing12);
  const Pose2 rel{r.range * c, r.range * s, WrapAngle(M_PI + in.bearing12 - in.bearing21)};
  // Eq. 45-50: frame 2 -> frame 1 is pose1 * rel * pose2^-1.
  Eigen::Matrix3d j_p1, j_rel, j_m, j_inv2, j_inv;
  const Pose2 in1 = Compose(in.pose1, rel, &j_p1, &j_rel);
  const Pose2 inv2 = Invert(in.pose2, &j_inv2);
  r.transform = Compose(in1, inv2, &j_m, &j_inv);
  // Jacobians of rel with respect to (range12, bearing12, range21, bearing21).
  Eigen::Matrix<double, 3, 4> j_z;
  const double dr1 = w1 / (w1 + w2), dr2 = w2 / (w1 + w2);
  j_z << dr1 * c, -r.range * s, dr2 * c, 0,  //
      dr1 * s, r.range * c, dr2 * s, 0,      //
      0, 1, 0, -1;
  const Eigen::Vector4d z_var(in.sigma_range1 * in.sigma_range1, in.sigma_bearing1 * in.sigma_bearing1,
                              in.sigma_range2 * in.sigma_range2, in.sigma_bearing2 * in.sigma_bearing2);
  const Eigen::Matrix3d a1 = j_m * j_p1, a_rel = j_m * j_rel, a2 = j_inv * j_inv2;
  const Eigen::Matrix<double, 3, 4> a_z = a_rel * j_z;
  r.cov = a1 * in.cov1 * a1.transpose() + a2 * in.cov2 * a2.transpose() + a_z * z_var.asDiagonal() * a_z.transpose();
  r.cov = 0.5 * (r.cov + r.cov.transpose()).eval();
  return r;
}

}  // namespace mapmesh
