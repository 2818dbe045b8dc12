#pragma once
// Least-squares joining of several robots' submap chains (issue J1, the `joining` back-end):
// the multi-robot form of SubmapJoiner (I-SLSJF; Downs 4.3).
//
// Chain c is one robot incarnation's closed submaps 0 .. K_c - 1 (and the open one last where
// the caller holds it: the own robot's, a peer's, or a silent robot's relayed). Submap k of chain c is an estimate, in its frame F_{c,k}, of the robot's pose
// at its end (the origin of F_{c,k+1}) and of its landmarks, with their joint covariance. The
// unknowns are every chain's frames X_{c,k} in the joined frame (the first chain's X_{0,0} is
// the joined frame's origin, fixed) and the landmarks; each landmark is a group of
// (robot, incarnation, key) references that the caller associates (the same landmark mapped by
// several robots, or by one robot's several incarnations). The joint estimate minimises
//   sum_{c,k} || z_{c,k} - h(X_{c,k}, X_{c,k+1}, L) ||^2 over P_{c,k}^-1
// by Levenberg-Marquardt on the shared kernel (common/solver/least_squares.h), started from the
// chains' origins as the caller places them (alignments) and the submaps composed along each
// chain. Every submap is independent of every other (each starts from no prior), so as long as
// each enters once nothing is counted twice, whichever robot relayed it.
//
// The caller's association is not trusted blindly: one wrong pairing of two robots' landmarks
// (neighbouring trees of a row, 1.5 m apart) drags a whole chain metres off, since a submap is
// one joint measurement and cannot down-weight one of its landmarks. So the join runs twice.
// First every reference is a landmark of its own, and the caller's pairings across chains are
// soft ties (the two positions equal within tie_sigma_m) under Cauchy's kernel, started from
// the caller's placement of the chains: pairings that the submaps contradict stop pulling. A
// pairing whose two positions end further apart than keep_tie_m is dropped. Then the pairings
// kept make the landmarks, and the exact join starts from the first solution.
//
// The first pass is what a join costs: with every reference its own landmark and every
// pairing a factor, it is several times the exact join's size. So when every chain to enter
// starts from a previous solve's frames (start_frames: the caller's last join), the pairings are
// judged on those frames instead: each pairing's two references where their chains' first
// submaps to hold them place them, kept within keep_tie_m as after the first pass. The frames
// of a join place the chains by all the landmarks they share, so a wrong pairing lies as far
// apart on them as after the first pass. That join is checked: when a submap's residual at its
// solution is far beyond what its covariance allows (recheck_sigmas), a wrong pairing was kept,
// and the join runs again with the first pass.
//
// A chain that shares too little with the others to be placed by the landmarks (fewer than
// min_shared_landmarks landmarks with the chains placed before it, in the given order, directly
// or through others) is left out and reported, as is one whose submaps repeat a landmark. Each
// landmark's covariance is its marginal of the inverse normal matrix at the solution, so the
// frames' uncertainty is in it.
//
// Pure: Eigen only, no clocks, threads or random numbers.

#include <Eigen/Core>
#include <compare>
#include <cstdint>
#include <map>
#include <set>
#include <span>
#include <vector>

#include "common/geometry/pose2.h"
#include "common/map/submap_codec.h"

namespace mapmesh {

// A landmark as one chain knows it: the robot's incarnation and its key there.
struct LandmarkRef {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  std::uint32_t key = 0;
  friend auto operator<=>(const LandmarkRef&, const LandmarkRef&) = default;
};

struct ChainInput {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  std::vector<const WireSubmap*> submaps;  // in chain order from index 0, without a gap (not null)
  Pose2 origin;                            // the chain's first frame in the joined frame: where to start
  // Where to start its frames 0, 1, ... instead (a previous solve's; fewer than the frames is
  // fine: the rest are composed along the submaps). Pairings are judged on landmarks where their
  // chain's first submap to hold them places them, so that a pairing dropped once is judged
  // afresh ...
  std::vector<Pose2> start_frames;
  // ... but a join judged on the start frames starts each landmark of its exact join where a
  // previous solve put it, by key, where given (the mean over the landmark's references).
  std::map<std::uint32_t, Eigen::Vector2d> start_landmarks;
  // The chain's first frame stays at `origin` (a check against an optimum that knows every
  // robot's start: the joined frame is the first chain's first frame, so `origin` is that
  // frame's inverse times the chain's start). Ignored for the first chain.
  bool origin_fixed = false;
};

struct NetworkOptions {
  int max_iterations = 50;
  // A chain enters when it shares this many landmarks with the chains already in.
  int min_shared_landmarks = 3;
  double tie_sigma_m = 0.1;  // the first pass's ties: two paired positions equal within this ...
  double tie_cauchy = 2.0;   // ... under Cauchy's kernel of this scale (in tie sigmas)
  double keep_tie_m = 0.5;   // a pairing whose positions end further apart is dropped
  // A chain that enters without start frames while the first chain has them is placed alone
  // against the others' frames (its references tied to where they hold the references paired
  // with them), and the pairings are judged on the frames (false: the first pass over every
  // chain, the baseline).
  bool place_new_chains_alone = true;
  // Judge the pairings on the chains' start frames when every chain to enter has them (false:
  // the first pass at every join) ...
  bool judge_on_start_frames = true;
  // ... and run the join again with the first pass when one so judged leaves a submap's
  // chi-square this many of its standard deviations (sqrt(2 m) for m measurements) above its
  // mean m. Consistent submaps stay within 3 (park4, 16 agents: at most 2.9 over 1616 joins);
  // a wrong pairing of two trees 1.5 m apart, with landmarks known to 5 cm, adds about 900 to
  // a submap's chi-square of mean about 60: some 75 deviations.
  double recheck_sigmas = 10.0;
  // After the exact join, each chain's variance factor: the chi-square of its submaps'
  // residuals over their redundancy (the residuals' count less the chain's share of the
  // variables). A chain whose factor exceeds 1 by more than this many of its standard deviations
  // (sqrt(2 / redundancy)) has its information divided by it and the join is solved again, at
  // most max_calibrations times (0: never). Submaps whose model is right stay within it and
  // cost nothing; a robot whose camera errs beyond its covariance (MRCLAM) weighs less.
  double calibrate_sigmas = 0.0;
  int max_calibrations = 3;
};

struct NetworkLandmark {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();
  std::vector<LandmarkRef> refs;  // every chain's name for it, in chain order
};

struct NetworkResult {
  std::vector<NetworkLandmark> landmarks;  // every landmark of the chains that entered
  // Per caller group: the landmark that holds it (the one with the first chain's reference when
  // its pairings were split), -1 when no chain that entered holds it.
  std::vector<int> of_group;
  std::vector<bool> joined;                // per input chain: whether it entered
  std::vector<Pose2> origins;              // per input chain: its first frame as solved (as given if left out)
  std::vector<std::vector<Pose2>> frames;  // per input chain: every frame as solved (empty if left out)
  int iterations = 0;
  bool converged = false;
  bool solved = false;  // false: nothing could be solved (the first chain left out, or a singular system)
  double cost = 0.0;    // 1/2 the sum of the squared whitened residuals at the solution
  int submaps = 0;      // submaps joined
  int ties = 0;         // pairings across chains offered ...
  // ... and dropped: between two chains that entered, their references kept as two landmarks
  // (by the first pass, or on the start frames; a pairing that others of its group already
  // imply is not dropped).
  int ties_dropped = 0;
  bool first_pass = true;  // false: the pairings were judged on the start frames
  int placed_alone = 0;    // chains without start frames placed alone before the pairings were judged on frames
  bool rechecked = false;  // judged on the start frames, refused by its residuals, and run with the first pass
  // ... whose first pass kept the very pairings the start frames had (its submaps' excesses
  // then cleared in the memo).
  bool recheck_unchanged = false;
  // Judged on the start frames with a submap beyond recheck_sigmas whose excess the memo had
  // cleared, so not rechecked.
  bool recheck_spared = false;
  // Per input chain: the variance factor its information was divided by (1 where none, or left
  // out), and the solves the calibration added (NetworkOptions::calibrate_sigmas).
  std::vector<double> variance_factors;
  int calibrations = 0;

  // The landmark of a caller group, or null.
  const NetworkLandmark* OfGroup(int group) const {
    if (group < 0 || static_cast<std::size_t>(group) >= of_group.size() || of_group[group] < 0) return nullptr;
    return &landmarks[static_cast<std::size_t>(of_group[group])];
  }
};

// The submaps' information matrices (their covariance's inverse, O(n^3) each), kept from one
// join to the next. A closed submap's is computed once; an open submap changes under one
// identity, so an entry whose covariance factor differs from the submap's is computed afresh.
// Entries that a join does not use are dropped at its end.
class SubmapInformation {
 public:
  const Eigen::MatrixXd& Of(const WireSubmap& s);
  // Drops the entries not asked for since the last call.
  void Sweep();
  std::size_t size() const { return entries_.size(); }
  int computed() const { return computed_; }  // information matrices computed so far

 private:
  struct Entry {
    Eigen::MatrixXd l, info;
    bool used = true;
  };
  std::map<SubmapId, Entry> entries_;
  int computed_ = 0;
};

// What the rechecks learnt, kept from one join to the next (NetworkOptions::recheck_sigmas):
// per submap, the excess of its chi-square (in its standard deviations) at which a recheck's
// first pass kept exactly the pairings that the start frames had kept. Such an excess is the
// submap's own (a sensor erring beyond its covariance, as MRCLAM's cameras do), not a wrong
// pairing's, and a first pass cannot mend it: a later join judged on the start frames is
// rechecked for that submap only once its excess exceeds this one by recheck_sigmas (a wrong
// pairing adds some 75). Entries of submaps a join does not take are dropped at its end.
class RecheckMemo {
 public:
  // The excess cleared for this submap, or -infinity.
  double Cleared(const SubmapId& id) const;
  void Clear(const SubmapId& id, double excess) { cleared_[id] = excess; }
  // Keeps only the entries of these submaps.
  void KeepOnly(const std::set<SubmapId>& ids);
  std::size_t size() const { return cleared_.size(); }

 private:
  std::map<SubmapId, double> cleared_;
};

// Joins the chains (the first is the joined frame's: its origin is fixed, and it always enters
// unless malformed). `groups` names the landmark group of each associated reference (ids from
// 0); a reference it does not name is a landmark of its own. A group that one submap would
// reach twice is split there.
// With `information`, the submaps' information matrices come from it (and stay in it); with
// `memo`, what the rechecks learnt is read from and written to it.
NetworkResult JoinSubmapNetwork(std::span<const ChainInput> chains, const std::map<LandmarkRef, int>& groups,
                                const NetworkOptions& options = {}, SubmapInformation* information = nullptr,
                                RecheckMemo* memo = nullptr);

}  // namespace mapmesh
