#include "agent/relay_policy.h"

#include <cmath>

namespace mapmesh {
namespace {

// Whether two transforms of a frame place the point `at` of it within tol_m of each other and
// turn it within tol_deg.
bool Within(const Pose2& a, const Pose2& b, const Eigen::Vector2d& at, double tol_m, double tol_deg) {
  return (a.Apply(at) - b.Apply(at)).norm() <= tol_m && std::abs(WrapAngle(a.theta - b.theta)) <= DegToRad(tol_deg);
}

}  // namespace

bool RelayPolicy::Agree(const Pose2& a, const Pose2& b, const Eigen::Vector2d& at) const {
  return Within(a, b, at, options_.relay_tolerance_m, options_.relay_tolerance_deg);
}

RelayPolicy::Overlap RelayPolicy::Compare(const LandmarkMap& witness, const LandmarkMap& map, const Pose2& placement,
                                          int* inliers) const {
  const AlignmentResult r = VerifyAlignment(witness, map, placement, options_.align);
  if (r.covered < options_.align.min_inliers) return Overlap::kNone;  // the witness has not mapped there
  if (!r.accepted() || static_cast<double>(r.inliers.size()) < options_.relay_min_agreement * r.covered ||
      !Agree(r.transform, placement, Centroid(map))) {
    return Overlap::kDisagrees;
  }
  if (inliers != nullptr) *inliers = static_cast<int>(r.inliers.size());
  return Overlap::kAgrees;
}

std::optional<PeerKey> RelayPolicy::FirstConflict(const PeerStates& peers, const PeerState& p,
                                                  const Pose2& to_own) const {
  for (const auto& [key, q] : peers) {
    if (&q == &p || !q.direct || q.direct->map.empty()) continue;
    // A frozen peer this relay re-placed is the relay's to bring: its own copy is no witness.
    if (q.superseded_by == p.key) continue;
    // q's map as we placed it, against p's global map where p placed it: where they overlap,
    // p's map must verify there, at the same transform.
    if (Compare(TransformMap(q.direct->map, q.direct->to_own), p.global, to_own) == Overlap::kDisagrees) return key;
  }
  return std::nullopt;
}

RelayPolicy::Evidence RelayPolicy::Weigh(const PeerStates& peers, const PeerState& q, const Pose2& placement,
                                         const LandmarkMap& own_local) const {
  const LandmarkMap& theirs = q.Map();
  Evidence e;
  auto weigh = [&](const LandmarkMap& witness) {
    int inliers = 0;
    switch (Compare(witness, theirs, placement, &inliers)) {
      case Overlap::kNone: break;
      case Overlap::kAgrees:
        ++e.supporters;
        e.inliers += inliers;
        break;
      case Overlap::kDisagrees: ++e.against; break;
    }
  };
  weigh(own_local);
  for (const auto& [key, w] : peers) {
    if (&w == &q || !w.direct || w.direct->map.empty() || key.robot == q.key.robot) continue;
    weigh(TransformMap(w.direct->map, w.direct->to_own));
  }
  return e;
}

std::optional<AlignmentResult> RelayPolicy::Refutation(const PeerStates& peers, const PeerState& p, const Pose2& to_own,
                                                       const PeerState& q, const LandmarkMap& own_local,
                                                       std::mt19937_64& rng) const {
  // Where p's global map places q: q's map aligned to it (it holds q's landmarks as p fused them).
  const LandmarkMap& theirs = q.Map();
  AlignmentOptions find = options_.align;
  find.ambiguity_ratio = 2.0;  // the best placement: the evidence decides ...
  find.max_iterations = 300;   // ... among few: a relay that holds q's map matches most of it
  AlignmentResult r = AlignMaps(TransformMap(p.global, to_own), theirs, find, rng);
  if (!r.accepted() || static_cast<double>(r.inliers.size()) < options_.refute_min_share * theirs.size()) {
    return std::nullopt;
  }
  // Placements this close are two fits of one alignment (of a bent map, say), not a false one.
  const Pose2 ours = q.to_own;
  const Eigen::Vector2d at = Centroid(theirs);
  if (Within(r.transform, ours, at, options_.refute_min_offset_m, options_.refute_min_offset_deg)) return std::nullopt;
  const Evidence held = Weigh(peers, q, ours, own_local);
  const Evidence relay = Weigh(peers, q, r.transform, own_local);
  const bool relay_better = relay.supporters > 0 && (relay.against < held.against ||
                                                     (relay.against == held.against && relay.inliers > held.inliers));
  if (!relay_better && held.against <= held.supporters) return std::nullopt;
  if (q.Frozen() && relay.supporters == 0) return std::nullopt;
  r.cov = r.cov + p.to_own_cov;  // the relay's frame is placed with that uncertainty
  return r;
}

}  // namespace mapmesh
