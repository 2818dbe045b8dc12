#pragma once
// Multi-robot map joining by least squares (Downs 4.3, in its information-weighted form; the
// agent's `fusion: joining`): the own local map and every aligned peer's local map are joined
// into one estimate of the landmarks in the own frame, together with each peer map's frame.
// Unknowns: the global landmarks g_k and, per peer source s, the transform T_s of its frame into
// ours. Measurements: each own landmark is g_k with its covariance; each peer landmark is
// T_s^-1(g_k) with its covariance in the peer's frame. The association (which source landmarks
// are one landmark) comes from the cloned global map's gates (BuildGlobalMap); its means start
// the Gauss-Newton iterations, the alignments the transforms. The transforms are estimated
// from the landmarks themselves, so the alignments' covariances (found from the same landmarks)
// are not added again: a prior 10^4 times weaker only fixes the frame of a source nothing else
// ties down. The measurements are weighted by Huber's kernel (iteratively reweighted least
// squares), so a biased copy of a landmark does not drag the others. Each landmark's covariance
// is its marginal of the inverse (weighted) normal matrix, so the uncertainty of the frames is
// in it.
//
// Nothing is counted twice as long as each robot's measurements enter once: the sources are
// one-hop LOCAL maps only (the own robot's and each aligned peer's), never a peer's global map,
// which already holds fused copies of ours and of others'. Within one local map the landmarks
// count as independent (only marginals travel); the shared part of their errors, the robot's
// pose error in its frame, is what the estimated transform absorbs.

#include <span>

#include "common/merge/global_map.h"

namespace mapmesh {

struct JoiningOptions {
  // Huber's constant on each landmark measurement's Mahalanobis residual (in sigmas; the usual
  // 1.345, 95 % efficiency on Gaussian errors); 0 for plain least squares. A landmark copy that
  // disagrees with the others (a map's bias, a bent stretch of one robot's map) then pulls with
  // a weight that falls as 1/residual instead of its full information.
  double huber = 1.345;
  // The weights are recomputed after each of the first `reweightings` Gauss-Newton steps, then
  // held while the steps converge (to 1e-7) on the weighted problem.
  int reweightings = 5;
  int max_iterations = 20;
};

struct JoiningStats {
  int downweighted = 0;  // measurements the robust kernel weighs less than 1 at the end
  int iterations = 0;
  bool converged = false;
  int unknowns = 0;
  int measurements = 0;
  bool solved = false;  // false: the normal matrix could not be factored; the association build was kept
};

// The joined map: `associated` (BuildGlobalMap of the same local map and sources) with every
// landmark's mean and covariance re-estimated jointly. sources must be the ones `associated`
// was built from.
GlobalMap JoinMaps(const LandmarkMap& local, RobotId self, std::uint32_t self_incarnation,
                   std::span<const MapSource> sources, const GlobalMap& associated, JoiningStats* stats = nullptr,
                   const JoiningOptions& options = {});

}  // namespace mapmesh
