#include "common/geometry/rigid_fit.h"

#include <cmath>

namespace mapmesh {

std::optional<Pose2> FitRigid2D(const std::vector<Eigen::Vector2d>& src, const std::vector<Eigen::Vector2d>& dst) {
  if (src.size() != dst.size() || src.size() < 2) return std::nullopt;
  const double n = static_cast<double>(src.size());
  Eigen::Vector2d ms = Eigen::Vector2d::Zero(), md = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i) {
    ms += src[i];
    md += dst[i];
  }
  ms /= n;
  md /= n;
  // In 2D the optimal rotation angle is atan2 of the summed cross and dot products of the
  // centred pairs (the closed form of Umeyama's SVD solution).
  double sxx = 0.0, sxy = 0.0, spread = 0.0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const Eigen::Vector2d a = src[i] - ms, b = dst[i] - md;
    sxx += a.dot(b);
    sxy += a.x() * b.y() - a.y() * b.x();
    spread += a.squaredNorm();
  }
  if (!(spread > 1e-12 * n) || !std::isfinite(spread)) return std::nullopt;
  const double theta = std::atan2(sxy, sxx);
  const Pose2 rot{0.0, 0.0, theta};
  const Eigen::Vector2d t = md - rot.Apply(ms);
  return Pose2{t.x(), t.y(), theta};
}

std::optional<Pose2> FitRigid2D(const Eigen::Vector2d& src1, const Eigen::Vector2d& src2, const Eigen::Vector2d& dst1,
                                const Eigen::Vector2d& dst2) {
  // [T(p1); T(p2)] = [S1 I; S2 I] theta with S = [x -y; y x]; with M = S1 - S2,
  // [cos, sin] = M^-1 (q1 - q2) (M = [dx -dy; dy dx], inverted by hand).
  const Eigen::Vector2d d = src1 - src2, q = dst1 - dst2;
  const double den = d.squaredNorm();
  if (!(den > 1e-18)) return std::nullopt;
  const double c = (d.x() * q.x() + d.y() * q.y()) / den;
  const double s = (d.x() * q.y() - d.y() * q.x()) / den;
  const double theta = std::atan2(s, c);  // projected onto a rotation
  const Pose2 rot{0.0, 0.0, theta};
  const Eigen::Vector2d t = 0.5 * (dst1 + dst2) - rot.Apply(0.5 * (src1 + src2));
  return Pose2{t.x(), t.y(), theta};
}

}  // namespace mapmesh
