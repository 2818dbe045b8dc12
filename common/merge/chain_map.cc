#include "common/merge/chain_map.h"

#include <Eigen/Cholesky>
#include <stdexcept>

#include "common/slam/submap_slam.h"

namespace mapmesh {

std::size_t ChainMap::Extend(std::span<const WireSubmap* const> chain) {
  std::size_t added = 0;
  while (!broken_ && joiner_.submaps() < chain.size()) {
    const WireSubmap& s = *chain[joiner_.submaps()];
    try {
      joiner_.Add({s.x, s.Covariance(), s.keys});
    } catch (const std::invalid_argument&) {
      broken_ = true;
      break;
    }
    ++added;
  }
  if (added > 0) map_ = JoinedLandmarkMap(joiner_.last(), false);
  return added;
}

const LandmarkMap& ChainMap::MapWith(const WireSubmap* open) {
  if (open == nullptr || broken_ || open->id.index != joiner_.submaps()) return map_;
  if (with_open_ && with_open_->joined == joiner_.submaps() && with_open_->index == open->id.index &&
      with_open_->closed_s == open->closed_s) {
    return with_open_->map;
  }
  const SubmapEstimate estimate{open->x, open->Covariance(), open->keys};
  try {
    with_open_ = WithOpen{joiner_.submaps(), open->id.index, open->closed_s,
                          JoinedLandmarkMap(joiner_.Solve(&estimate), false)};
  } catch (const std::invalid_argument&) {
    return map_;
  }
  return with_open_->map;
}

const WireSubmap* ChainMap::Summary(const WireSubmap& last) {
  if (broken_ || joiner_.submaps() == 0) return nullptr;
  if (summary_joined_ == joiner_.submaps()) return summary_ ? &*summary_ : nullptr;
  summary_joined_ = joiner_.submaps();
  summary_.reset();
  const JoinedMap& j = joiner_.last();
  const auto n = static_cast<Eigen::Index>(2 * j.keys.size());
  WireSubmap s;
  s.id = last.id;
  s.id.index |= kSummaryIndexBit;
  s.closed_s = last.closed_s;
  s.keys = j.keys;
  s.x.resize(3 + n);
  s.x.head<3>() << j.end.x, j.end.y, j.end.theta;
  for (std::size_t i = 0; i < j.means.size(); ++i) s.x.segment<2>(3 + 2 * static_cast<Eigen::Index>(i)) = j.means[i];
  Eigen::MatrixXd p(3 + n, 3 + n);
  p.topLeftCorner<3, 3>() = j.end_cov;
  if (n > 0) {
    p.topRightCorner(3, n) = j.end_cross;
    p.bottomLeftCorner(n, 3) = j.end_cross.transpose();
    p.bottomRightCorner(n, n) = j.cov;
  }
  // Never on the wire: the factor in full precision (SetCovariance rounds it to the wire's f32).
  const Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (p + p.transpose()));
  if (llt.info() != Eigen::Success || !p.allFinite()) return nullptr;
  s.l = llt.matrixL();
  summary_ = std::move(s);
  return &*summary_;
}

}  // namespace mapmesh
