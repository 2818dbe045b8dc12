#include "common/merge/submap_network.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <memory>
#include <optional>
#include <set>
#include <tuple>

#include "common/slam/submap_joiner.h"
#include "common/solver/least_squares.h"

namespace mapmesh {
namespace {

// One submap as a factor: its measurement and information p^-1 (the submap's, not copied),
// its chain and place in it, and the landmark slot of each of its landmarks.
struct Factor {
  SubmapId id;
  int chain = 0;
  int index = 0;  // k: it joins frames k and k + 1 of its chain
  Eigen::VectorXd z;
  const Eigen::MatrixXd* info = nullptr;
  std::vector<int> slots;
};

// Two slots whose positions should be equal (the first pass's pairings).
struct Tie {
  int a = 0, b = 0;
};

// The problem for the Levenberg-Marquardt driver: frames per chain (frame 0 of the first chain
// fixed), landmark slots, the submap factors and the ties.
class Network : public LeastSquaresProblem {
 public:
  std::vector<Factor> factors;
  std::vector<Tie> ties;
  double tie_sigma = 1.0;
  RobustKernel kernel;
  // A placing pass's ties of held slots to fixed positions (under the tie's sigma and kernel),
  // and a weak prior on each chain's first frame (chain index, where, and its sigmas in m and
  // rad), so that a chain the ties hold too little stays solvable.
  std::vector<std::pair<int, Eigen::Vector2d>> anchors;
  std::vector<std::pair<int, Pose2>> origin_priors;
  double origin_sigma_m = 1.0, origin_sigma_rad = 1.0;
  std::vector<std::vector<Pose2>> frames;   // per chain taken, its frames 0 .. K
  std::vector<std::vector<int>> frame_var;  // ... their variables (-1: fixed)
  // Per slot (of every reference's): its landmark position, and its variable (-1: a slot the
  // network does not hold); the slots it holds, ascending.
  std::vector<Eigen::Vector2d> slots;
  std::vector<int> slot_var;
  std::vector<int> held;
  bool Holds(int slot) const { return slot_var[static_cast<std::size_t>(slot)] >= 0; }
  const Eigen::Vector2d& At(int slot) const { return slots[static_cast<std::size_t>(slot)]; }
  std::vector<int> factor_handles, tie_handles;
  std::vector<int> sizes;  // the variables' sizes: frames (but the fixed origin), then slots
  // Per chain taken: the weight of its submaps' information (1 / its variance factor).
  std::vector<double> weight;
  double WeightOf(const Factor& f) const { return weight.empty() ? 1.0 : weight[static_cast<std::size_t>(f.chain)]; }

  // Per chain taken: the chi-square of its submaps' residuals at the current state under
  // their information as given (weights aside), and their redundancy: the residuals' count
  // less the chain's share of the variables (its frames, and of each landmark 2 / the number
  // of submaps that hold it).
  void ChainChiSquares(std::vector<double>* chi2, std::vector<double>* redundancy) const {
    chi2->assign(frames.size(), 0.0);
    redundancy->assign(frames.size(), 0.0);
    std::vector<int> holders(slots.size(), 0);
    for (const Factor& f : factors) {
      for (int g : f.slots) ++holders[static_cast<std::size_t>(g)];
    }
    for (const Factor& f : factors) {
      const auto c = static_cast<std::size_t>(f.chain);
      const Eigen::VectorXd e = Error(f, nullptr);
      (*chi2)[c] += e.dot(*f.info * e);
      (*redundancy)[c] += static_cast<double>(e.size());
      for (int g : f.slots) (*redundancy)[c] -= 2.0 / holders[static_cast<std::size_t>(g)];
    }
    for (std::size_t c = 0; c < frames.size(); ++c) {
      for (int v : frame_var[c]) (*redundancy)[c] -= v >= 0 ? 3.0 : 0.0;
    }
  }

  // Per factor: the excess of its chi-square over its mean at the current state, in its
  // standard deviations: (w e^T P^-1 e - m) / sqrt(2 m), m = the size of e, w its chain's
  // weight in `weights` (1 without).
  std::vector<double> Excesses(const std::vector<double>* weights = nullptr) const {
    std::vector<double> out;
    out.reserve(factors.size());
    for (const Factor& f : factors) {
      const Eigen::VectorXd e = Error(f, nullptr);
      const auto m = static_cast<double>(e.size());
      const double w = weights == nullptr ? 1.0 : (*weights)[static_cast<std::size_t>(f.chain)];
      out.push_back((w * e.dot(*f.info * e) - m) / std::sqrt(2.0 * m));
    }
    return out;
  }

  // One round of the calibration (NetworkOptions::calibrate_sigmas): each chain's variance
  // factor under `weights` (per chain taken: 1 / the factor its information is divided by),
  // and the weight of each whose factor exceeds 1 by more than `sigmas` of its standard
  // deviations divided by it. Returns whether any was.
  bool Calibrate(double sigmas, std::vector<double>* weights) const {
    std::vector<double> chi2, redundancy;
    ChainChiSquares(&chi2, &redundancy);
    bool beyond = false;
    for (std::size_t c = 0; c < weights->size(); ++c) {
      if (redundancy[c] < 1.0) continue;
      const double f = (*weights)[c] * chi2[c] / redundancy[c];
      if (f <= 1.0 + sigmas * std::sqrt(2.0 / redundancy[c])) continue;
      (*weights)[c] /= f;
      beyond = true;
    }
    return beyond;
  }

  double Linearise(BlockNormalEquations& eq) override {
    double cost = 0.0;
    Eigen::MatrixXd j, h;
    Eigen::VectorXd g;
    for (std::size_t i = 0; i < factors.size(); ++i) {
      const Factor& f = factors[i];
      const Eigen::VectorXd e = Error(f, &j);
      const double w = WeightOf(f);
      cost += 0.5 * w * e.dot(*f.info * e);
      SubmapNormalEquations(j, *f.info, e, &h, &g);
      if (w != 1.0) {
        h *= w;
        g *= w;
      }
      // Rows and columns of a fixed origin (the first chain's frame 0, or one held) are dropped.
      const bool fixed = frame_var[static_cast<std::size_t>(f.chain)][static_cast<std::size_t>(f.index)] < 0;
      if (fixed) {
        eq.AddInformation(factor_handles[i], h.bottomRightCorner(h.rows() - 3, h.cols() - 3), g.tail(g.size() - 3));
      } else {
        eq.AddInformation(factor_handles[i], h, g);
      }
    }
    Eigen::Matrix<double, 2, 4> jt;
    jt << Eigen::Matrix2d::Identity() / tie_sigma, -Eigen::Matrix2d::Identity() / tie_sigma;
    for (std::size_t i = 0; i < ties.size(); ++i) {
      const Eigen::Vector2d r = TieResidual(ties[i]);
      const double s = r.squaredNorm();
      cost += 0.5 * kernel.Rho(s);
      eq.Add(tie_handles[i], jt, r, kernel.Weight(s));
    }
    const Eigen::Matrix2d ja = Eigen::Matrix2d::Identity() / tie_sigma;
    for (std::size_t i = 0; i < anchors.size(); ++i) {
      const Eigen::Vector2d r = AnchorResidual(anchors[i]);
      const double s = r.squaredNorm();
      cost += 0.5 * kernel.Rho(s);
      eq.Add(anchor_handles[i], ja, r, kernel.Weight(s));
    }
    const Eigen::Matrix3d jo = OriginWhitening();
    for (std::size_t i = 0; i < origin_priors.size(); ++i) {
      const Eigen::Vector3d r = OriginResidual(origin_priors[i]);
      cost += 0.5 * r.squaredNorm();
      eq.Add(origin_handles[i], jo, r);
    }
    return cost;
  }
  double Cost() const override {
    double cost = 0.0;
    for (const Factor& f : factors) {
      const Eigen::VectorXd e = Error(f, nullptr);
      cost += 0.5 * WeightOf(f) * e.dot(*f.info * e);
    }
    for (const Tie& t : ties) cost += 0.5 * kernel.Rho(TieResidual(t).squaredNorm());
    for (const auto& a : anchors) cost += 0.5 * kernel.Rho(AnchorResidual(a).squaredNorm());
    for (const auto& o : origin_priors) cost += 0.5 * OriginResidual(o).squaredNorm();
    return cost;
  }
  void Step(const Eigen::VectorXd& dx) override {
    for (std::size_t c = 0; c < frames.size(); ++c) {
      for (std::size_t k = 0; k < frames[c].size(); ++k) {
        const int v = frame_var[c][k];
        if (v < 0) continue;
        const int o = offsets_[static_cast<std::size_t>(v)];
        Pose2& p = frames[c][k];
        p = p.Retract(dx.segment<3>(o));
      }
    }
    for (int slot : held) {
      slots[static_cast<std::size_t>(slot)] += dx.segment<2>(
          offsets_[static_cast<std::size_t>(slot_var[static_cast<std::size_t>(slot)])]);
    }
  }
  void Save() override {
    saved_frames_ = frames;
    saved_slots_ = slots;
  }
  void Restore() override {
    frames = saved_frames_;
    slots = saved_slots_;
  }
  void SetOffsets(const BlockNormalEquations& eq) {
    offsets_.resize(static_cast<std::size_t>(eq.variables()));
    for (int v = 0; v < eq.variables(); ++v) offsets_[static_cast<std::size_t>(v)] = eq.offset(v);
  }
  Eigen::Vector2d TieResidual(const Tie& t) const { return (At(t.a) - At(t.b)) / tie_sigma; }
  Eigen::Vector2d AnchorResidual(const std::pair<int, Eigen::Vector2d>& a) const {
    return (At(a.first) - a.second) / tie_sigma;
  }
  Eigen::Matrix3d OriginWhitening() const {
    return Eigen::Vector3d(1.0 / origin_sigma_m, 1.0 / origin_sigma_m, 1.0 / origin_sigma_rad).asDiagonal();
  }
  Eigen::Vector3d OriginResidual(const std::pair<int, Pose2>& o) const {
    const Pose2& p = frames[static_cast<std::size_t>(o.first)][0];
    return OriginWhitening() * Eigen::Vector3d(p.x - o.second.x, p.y - o.second.y, WrapAngle(p.theta - o.second.theta));
  }
  std::vector<int> anchor_handles, origin_handles;

 private:
  // The error h - z and, if asked, its Jacobian dh/dx over [X_k, X_k+1, L...].
  Eigen::VectorXd Error(const Factor& f, Eigen::MatrixXd* j) const {
    std::vector<Eigen::Vector2d> points;
    points.reserve(f.slots.size());
    for (int g : f.slots) points.push_back(At(g));
    const std::vector<Pose2>& chain = frames[static_cast<std::size_t>(f.chain)];
    const auto k = static_cast<std::size_t>(f.index);
    Eigen::VectorXd e = PredictSubmap(chain[k], chain[k + 1], points, j) - f.z;
    e(2) = WrapAngle(e(2));
    return e;
  }

  std::vector<int> offsets_;
  std::vector<std::vector<Pose2>> saved_frames_;
  std::vector<Eigen::Vector2d> saved_slots_;
};

// Union-find over slots.
class Unions {
 public:
  explicit Unions(std::size_t n = 0) : parent_(n, -1) {}
  int Find(int a) {
    const int p = parent_[static_cast<std::size_t>(a)];
    if (p < 0) return a;
    const int root = Find(p);
    parent_[static_cast<std::size_t>(a)] = root;
    return root;
  }
  void Join(int a, int b) {
    a = Find(a);
    b = Find(b);
    if (a != b) parent_[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
  }

 private:
  std::vector<int> parent_;  // per slot: its parent, -1 for a root
};

// The network of the chains of `order`, each reference in the slot slot_of names, with the
// ties given whose slots it holds, placed (not solved): frames and slots from start_frames
// and start_slots where given (else each chain's own start_frames, else composed along the
// chain from its origin; each slot where the first submap to hold it places it).
Network Place(std::span<const ChainInput> chains, const std::vector<std::size_t>& order,
              const std::map<LandmarkRef, int>& slot_of, std::size_t slot_count, const std::vector<Tie>& ties,
              const std::vector<std::vector<Pose2>>* start_frames, const std::map<int, Eigen::Vector2d>* start_slots,
              SubmapInformation& information, bool free_gauge = false) {
  Network net;
  std::vector<int>& sizes = net.sizes;
  net.slots.assign(slot_count, Eigen::Vector2d::Zero());
  net.slot_var.assign(slot_count, -1);
  for (std::size_t i = 0; i < order.size(); ++i) {
    const ChainInput& c = chains[order[i]];
    // From the given frames (the first pass's, or a previous solve's where the chain has them),
    // else composed along the submaps from the chain's origin.
    const std::vector<Pose2>& given = start_frames ? (*start_frames)[i] : c.start_frames;
    // The first chain's origin is the joined frame's; a chain whose origin is fixed stays at it.
    // (free_gauge: none is the joined frame's; a placing pass's chains are held by ties to fixed positions.)
    const bool gauge = i == 0 && !free_gauge;
    const bool fixed = gauge || c.origin_fixed;
    std::vector<Pose2> frames = {gauge ? Pose2{} : (given.empty() || c.origin_fixed ? c.origin : given[0])};
    std::vector<int> vars = {fixed ? -1 : static_cast<int>(sizes.size())};
    if (!fixed) sizes.push_back(3);
    for (std::size_t k = 0; k < c.submaps.size(); ++k) {
      const WireSubmap& w = *c.submaps[k];
      Factor f;
      f.id = w.id;
      f.chain = static_cast<int>(i);
      f.index = static_cast<int>(k);
      f.z = w.x;
      f.z(2) = WrapAngle(f.z(2));
      f.info = &information.Of(w);
      for (std::uint32_t key : w.keys) f.slots.push_back(slot_of.at({c.robot, c.incarnation, key}));
      for (std::size_t j = 0; j < f.slots.size(); ++j) {
        const auto slot = static_cast<std::size_t>(f.slots[j]);
        if (net.slot_var[slot] < 0) {
          net.slot_var[slot] = 0;  // held (its variable is numbered below)
          net.slots[slot] = frames.back().Apply(w.x.segment<2>(3 + 2 * static_cast<Eigen::Index>(j)));
        }
      }
      frames.push_back(k + 1 < given.size() ? given[k + 1] : frames.back() * Pose2{w.x(0), w.x(1), w.x(2)});
      vars.push_back(static_cast<int>(sizes.size()));
      sizes.push_back(3);
      net.factors.push_back(std::move(f));
    }
    net.frames.push_back(std::move(frames));
    net.frame_var.push_back(std::move(vars));
  }
  for (std::size_t slot = 0; slot < slot_count; ++slot) {
    if (net.slot_var[slot] < 0) continue;
    net.held.push_back(static_cast<int>(slot));
    net.slot_var[slot] = static_cast<int>(sizes.size());
    sizes.push_back(2);
  }
  if (start_slots) {
    for (const auto& [slot, l] : *start_slots) {
      if (net.Holds(slot)) net.slots[static_cast<std::size_t>(slot)] = l;
    }
  }
  for (const Tie& t : ties) {
    if (net.Holds(t.a) && net.Holds(t.b)) net.ties.push_back(t);
  }
  return net;
}

// Declares every factor of the network to eq (submaps, ties, anchors, origin priors), then
// finalizes it and gives the network its variables' offsets.
void CoupleAll(Network& net, BlockNormalEquations& eq) {
  for (const Factor& f : net.factors) {
    std::vector<int> vars;
    const auto c = static_cast<std::size_t>(f.chain);
    const auto k = static_cast<std::size_t>(f.index);
    if (net.frame_var[c][k] >= 0) vars.push_back(net.frame_var[c][k]);
    vars.push_back(net.frame_var[c][k + 1]);
    for (int g : f.slots) vars.push_back(net.slot_var[static_cast<std::size_t>(g)]);
    net.factor_handles.push_back(eq.Couple(vars));
  }
  const auto var = [&](int slot) { return net.slot_var[static_cast<std::size_t>(slot)]; };
  for (const Tie& t : net.ties) net.tie_handles.push_back(eq.Couple({var(t.a), var(t.b)}));
  for (const auto& a : net.anchors) net.anchor_handles.push_back(eq.Couple({var(a.first)}));
  for (const auto& o : net.origin_priors) {
    net.origin_handles.push_back(eq.Couple({net.frame_var[static_cast<std::size_t>(o.first)][0]}));
  }
  eq.Finalize();
  net.SetOffsets(eq);
}

LevenbergMarquardtOptions JoinIterations(int max_iterations) {
  LevenbergMarquardtOptions lm;
  lm.max_iterations = max_iterations;
  // Micrometres and a millionth of the cost are far below what a map can tell apart.
  lm.step_tolerance = 1e-6;
  lm.function_tolerance = 1e-6;
  // Every join but a first one starts from the last join's state: once a step is accepted,
  // the Gauss-Newton step tells when it is there.
  lm.undamped_below = lm.initial_lambda;
  return lm;
}

// One solve: the network Place gives, with the ties under `kernel` at tie_sigma. On return,
// the network holds the solution and eq its normal equations.
struct Solved {
  Network net;
  LevenbergMarquardtReport report;
};

Solved Solve(std::span<const ChainInput> chains, const std::vector<std::size_t>& order,
             const std::map<LandmarkRef, int>& slot_of, std::size_t slot_count, const std::vector<Tie>& ties,
             double tie_sigma, const RobustKernel& kernel, const std::vector<std::vector<Pose2>>* start_frames,
             const std::map<int, Eigen::Vector2d>* start_slots, int max_iterations, SubmapInformation& information,
             std::unique_ptr<BlockNormalEquations>* eq_out, const std::vector<double>* weights = nullptr) {
  Solved s;
  s.net = Place(chains, order, slot_of, slot_count, ties, start_frames, start_slots, information);
  Network& net = s.net;
  if (weights != nullptr) net.weight = *weights;
  net.tie_sigma = tie_sigma;
  net.kernel = kernel;
  *eq_out = std::make_unique<BlockNormalEquations>(net.sizes);
  BlockNormalEquations& eq = **eq_out;
  CoupleAll(net, eq);
  s.report = MinimiseLevenbergMarquardt(net, eq, JoinIterations(max_iterations));
  return s;
}

// The placing pass: the chains of `fresh` (no previous solve's frames) solved alone, their
// references tied under the first pass's kernel to each other (`among`) and to fixed positions
// (`anchors`: where the chains that have frames hold the references they are paired with),
// each chain's first frame weakly held where it starts (10 m, 1 rad: a chain the ties do not
// hold stays where it was placed). Returns each fresh chain's frames as solved.
std::vector<std::vector<Pose2>> PlaceAlone(std::span<const ChainInput> chains, const std::vector<std::size_t>& fresh,
                                           const std::map<LandmarkRef, int>& slot_of, std::size_t slot_count,
                                           const std::vector<Tie>& among,
                                           const std::vector<std::pair<int, Eigen::Vector2d>>& anchors,
                                           double tie_sigma, const RobustKernel& kernel, int max_iterations,
                                           SubmapInformation& information) {
  Network net = Place(chains, fresh, slot_of, slot_count, among, nullptr, nullptr, information, /*free_gauge=*/true);
  net.tie_sigma = tie_sigma;
  net.kernel = kernel;
  for (const auto& a : anchors) {
    if (net.Holds(a.first)) net.anchors.push_back(a);
  }
  for (std::size_t i = 0; i < fresh.size(); ++i) {
    if (net.frame_var[i][0] >= 0) net.origin_priors.push_back({static_cast<int>(i), net.frames[i][0]});
  }
  net.origin_sigma_m = 10.0;
  net.origin_sigma_rad = 1.0;
  BlockNormalEquations eq(net.sizes);
  CoupleAll(net, eq);
  MinimiseLevenbergMarquardt(net, eq, JoinIterations(max_iterations));
  return net.frames;
}

// The join, step by step (JoinSubmapNetwork): the input indexed, the pairings offered, the
// chains that enter, the placing pass, the pairings judged and their unions, the exact join
// from where they were judged, the recheck, the calibration and the result. One instance per
// join; its members are what the steps share.
class NetworkJoin {
 public:
  NetworkJoin(std::span<const ChainInput> chains, const NetworkOptions& options, SubmapInformation& info,
              RecheckMemo* memo)
      : chains_(chains), options_(options), info_(info), memo_(memo) {}

  NetworkResult Run(const std::map<LandmarkRef, int>& groups);

 private:
  void IndexSlots();
  void OfferTies(const std::map<LandmarkRef, int>& groups);
  std::vector<std::size_t> Enter(const std::vector<Tie>& usable) const;
  void PlaceNewChainsAlone(const std::vector<std::size_t>& first_order, const RobustKernel& first_kernel);
  std::vector<Tie> KeepTies(const Network& at);
  std::map<int, Eigen::Vector2d> UnionStarts(const Network& at, bool first_pass);
  bool Beyond(const std::vector<double>& excess, bool* spared, std::vector<std::pair<SubmapId, double>>* list) const;
  bool StandsOnStartFrames();
  void CountDroppedTies();
  std::vector<double> Calibrate();
  void Result(const std::map<LandmarkRef, int>& groups);

  std::span<const ChainInput> chains_;
  const NetworkOptions& options_;
  SubmapInformation& info_;
  RecheckMemo* memo_;
  NetworkResult out_;
  std::vector<ChainInput> with_frames_;  // the chains with the placing pass's frames (chains_ then views it)
  // Every reference its own slot, in chain order; per slot its chain and the submaps that hold it.
  std::map<LandmarkRef, int> slot_of_;
  std::vector<LandmarkRef> refs_;
  std::vector<bool> wellformed_;
  std::vector<std::size_t> chain_of_slot_;
  std::vector<std::vector<int>> submaps_of_slot_;
  std::vector<Tie> ties_;  // the caller's pairings across chains
  std::unique_ptr<BlockNormalEquations> eq_;
  Solved first_, second_;
  std::vector<std::size_t> order_;          // the chains of the exact join, in order
  std::map<LandmarkRef, int> landmark_of_;  // per reference: its union (the exact join's landmark)
  Unions unions_;
  // A join judged on the start frames: its submaps beyond the recheck with their excesses.
  std::vector<std::pair<SubmapId, double>> judged_excess_;
};

// Every reference its own slot, in chain order; a chain whose submaps name one key twice (or
// none at all) is malformed and stays out.
void NetworkJoin::IndexSlots() {
  wellformed_.assign(chains_.size(), true);
  for (std::size_t c = 0; c < chains_.size(); ++c) {
    if (chains_[c].submaps.empty()) wellformed_[c] = false;
    for (const WireSubmap* s : chains_[c].submaps) {
      std::set<std::uint32_t> keys(s->keys.begin(), s->keys.end());
      if (keys.size() != s->keys.size()) wellformed_[c] = false;
      for (std::uint32_t key : s->keys) {
        const LandmarkRef ref{chains_[c].robot, chains_[c].incarnation, key};
        if (slot_of_.emplace(ref, static_cast<int>(refs_.size())).second) refs_.push_back(ref);
      }
    }
  }
  std::map<std::pair<RobotId, std::uint32_t>, std::size_t> chain_index;  // (robot, incarnation) -> its chain
  for (std::size_t c = 0; c < chains_.size(); ++c) chain_index[{chains_[c].robot, chains_[c].incarnation}] = c;
  chain_of_slot_.reserve(refs_.size());
  for (const LandmarkRef& ref : refs_) chain_of_slot_.push_back(chain_index.at({ref.robot, ref.incarnation}));
  // The submaps that hold each slot, to refuse a union that would name one landmark twice in one.
  submaps_of_slot_.assign(refs_.size(), {});
  int submap_count = 0;
  for (const ChainInput& c : chains_) {
    for (const WireSubmap* s : c.submaps) {
      for (std::uint32_t key : s->keys) {
        submaps_of_slot_[static_cast<std::size_t>(slot_of_.at({c.robot, c.incarnation, key}))].push_back(submap_count);
      }
      ++submap_count;
    }
  }
}

// The caller's pairings across chains: every two references of one group in different chains.
void NetworkJoin::OfferTies(const std::map<LandmarkRef, int>& groups) {
  std::map<int, std::vector<int>> members;
  for (const auto& [ref, g] : groups) {
    const auto it = slot_of_.find(ref);
    if (it != slot_of_.end()) members[g].push_back(it->second);
  }
  for (const auto& [g, slots] : members) {
    for (std::size_t i = 0; i < slots.size(); ++i) {
      for (std::size_t j = i + 1; j < slots.size(); ++j) {
        const LandmarkRef& a = refs_[static_cast<std::size_t>(slots[i])];
        const LandmarkRef& b = refs_[static_cast<std::size_t>(slots[j])];
        if (a.robot != b.robot || a.incarnation != b.incarnation) ties_.push_back({slots[i], slots[j]});
      }
    }
  }
  out_.ties = static_cast<int>(ties_.size());
}

// The chains that enter: the first, then each tied to those in by enough landmarks, until none
// more is.
std::vector<std::size_t> NetworkJoin::Enter(const std::vector<Tie>& usable) const {
  std::vector<std::size_t> order = {0};
  std::vector<bool> in(chains_.size(), false);
  in[0] = true;
  for (bool more = true; more;) {
    more = false;
    for (std::size_t c = 1; c < chains_.size(); ++c) {
      if (in[c] || !wellformed_[c]) continue;
      std::set<int> shared;  // this chain's slots tied to a chain in
      for (const Tie& t : usable) {
        const std::size_t ca = chain_of_slot_[static_cast<std::size_t>(t.a)];
        const std::size_t cb = chain_of_slot_[static_cast<std::size_t>(t.b)];
        if (ca == c && in[cb]) shared.insert(t.a);
        if (cb == c && in[ca]) shared.insert(t.b);
      }
      if (static_cast<int>(shared.size()) < options_.min_shared_landmarks) continue;
      in[c] = true;
      order.push_back(c);
      more = true;
    }
  }
  return order;
}

// Chains that enter without a previous solve's frames (new ones) while the first has them:
// placed alone against the others' frames (the placing pass), so that every chain has frames
// and the pairings are judged on them, without a first pass over every chain (whose cost
// grows with the chains: 48 of them, seconds).
void NetworkJoin::PlaceNewChainsAlone(const std::vector<std::size_t>& first_order, const RobustKernel& first_kernel) {
  if (!options_.judge_on_start_frames || !options_.place_new_chains_alone || chains_[0].start_frames.empty()) return;
  std::vector<std::size_t> known, fresh;
  for (std::size_t c : first_order) (chains_[c].start_frames.empty() ? fresh : known).push_back(c);
  if (fresh.empty()) return;
  std::vector<bool> is_fresh(chains_.size(), false);
  for (std::size_t c : fresh) is_fresh[c] = true;
  const Network held = Place(chains_, known, slot_of_, refs_.size(), {}, nullptr, nullptr, info_);
  std::vector<Tie> among;
  std::vector<std::pair<int, Eigen::Vector2d>> anchors;
  for (const Tie& t : ties_) {
    const bool fa = is_fresh[chain_of_slot_[static_cast<std::size_t>(t.a)]];
    const bool fb = is_fresh[chain_of_slot_[static_cast<std::size_t>(t.b)]];
    if (fa && fb) among.push_back(t);
    if (fa && !fb && held.Holds(t.b)) anchors.push_back({t.a, held.At(t.b)});
    if (fb && !fa && held.Holds(t.a)) anchors.push_back({t.b, held.At(t.a)});
  }
  const std::vector<std::vector<Pose2>> frames = PlaceAlone(chains_, fresh, slot_of_, refs_.size(), among, anchors,
                                                            options_.tie_sigma_m, first_kernel, options_.max_iterations,
                                                            info_);
  with_frames_.assign(chains_.begin(), chains_.end());
  for (std::size_t i = 0; i < fresh.size(); ++i) with_frames_[fresh[i]].start_frames = frames[i];
  chains_ = with_frames_;
  out_.placed_alone = static_cast<int>(fresh.size());
}

// The pairings kept on the network they were judged on; their unions are the landmarks. A union
// that one submap would reach twice keeps the pairings made first (closest first) and drops the
// rest. Returns the pairings used.
std::vector<Tie> NetworkJoin::KeepTies(const Network& at) {
  std::vector<std::pair<double, Tie>> kept;
  for (const Tie& t : at.ties) {
    const double d = (at.At(t.a) - at.At(t.b)).norm();
    if (d <= options_.keep_tie_m) kept.push_back({d, t});
  }
  std::sort(kept.begin(), kept.end(), [](const auto& x, const auto& y) {
    return std::tie(x.first, x.second.a, x.second.b) < std::tie(y.first, y.second.a, y.second.b);
  });
  unions_ = Unions(refs_.size());
  std::map<int, std::set<int>> submaps_of_root;  // per union root: the submaps its slots are in
  auto submaps_of = [&](int root) -> std::set<int>& {
    auto [it, fresh] = submaps_of_root.try_emplace(root);
    if (fresh) {
      const std::vector<int>& s = submaps_of_slot_[static_cast<std::size_t>(root)];
      it->second.insert(s.begin(), s.end());
    }
    return it->second;
  };
  std::vector<Tie> used;
  for (const auto& [d, t] : kept) {
    const int ra = unions_.Find(t.a), rb = unions_.Find(t.b);
    if (ra == rb) continue;
    std::set<int>& sa = submaps_of(ra);
    std::set<int>& sb = submaps_of(rb);
    const bool overlap = std::any_of(sa.begin(), sa.end(), [&](int s) { return sb.count(s) > 0; });
    if (overlap) continue;
    unions_.Join(ra, rb);
    const int root = unions_.Find(ra);  // the smaller of the two: its set takes the other's
    std::set<int>& into = root == ra ? sa : sb;
    std::set<int>& from = root == ra ? sb : sa;
    into.insert(from.begin(), from.end());
    submaps_of_root.erase(root == ra ? rb : ra);
    used.push_back(t);
  }
  return used;
}

// Each union's start: the mean of its slots' positions on the network judged; on the start
// frames, where a previous solve put the landmarks, where the chains say.
std::map<int, Eigen::Vector2d> NetworkJoin::UnionStarts(const Network& at, bool first_pass) {
  const auto mean_by_union = [&](const auto& position) {
    std::map<int, std::pair<Eigen::Vector2d, int>> sums;
    for (int slot : at.held) {
      const std::optional<Eigen::Vector2d> p = position(slot, at.At(slot));
      if (!p) continue;
      auto [it, fresh] = sums.try_emplace(unions_.Find(slot), *p, 1);
      if (!fresh) {
        it->second.first += *p;
        ++it->second.second;
      }
    }
    std::map<int, Eigen::Vector2d> means;
    for (const auto& [root, sum] : sums) means[root] = sum.first / sum.second;
    return means;
  };
  std::map<int, Eigen::Vector2d> start = mean_by_union([](int, const Eigen::Vector2d& l) {
    return std::optional<Eigen::Vector2d>(l);
  });
  if (!first_pass) {
    const auto previous = mean_by_union([&](int slot, const Eigen::Vector2d&) -> std::optional<Eigen::Vector2d> {
      const LandmarkRef& ref = refs_[static_cast<std::size_t>(slot)];
      const auto& given = chains_[chain_of_slot_[static_cast<std::size_t>(slot)]].start_landmarks;
      const auto it = given.find(ref.key);
      if (it == given.end()) return std::nullopt;
      return it->second;
    });
    for (const auto& [root, l] : previous) start[root] = l;
  }
  return start;
}

// Whether a submap's residual says a pairing of the join is wrong: its excess beyond
// recheck_sigmas, and beyond what a recheck found its own (*spared: some submap was beyond the
// check only by what the memo cleared). The submaps beyond go to `list`.
bool NetworkJoin::Beyond(const std::vector<double>& excess, bool* spared,
                         std::vector<std::pair<SubmapId, double>>* list) const {
  bool any = false;
  for (std::size_t i = 0; i < excess.size(); ++i) {
    if (excess[i] <= options_.recheck_sigmas) continue;
    const SubmapId& id = second_.net.factors[i].id;
    if (memo_ != nullptr && excess[i] <= memo_->Cleared(id) + options_.recheck_sigmas) {
      *spared = true;
      continue;
    }
    any = true;
    if (list != nullptr) list->push_back({id, excess[i]});
  }
  return any;
}

// A join judged on the start frames stands unless a submap's residual says a pairing is wrong
// (Beyond) ... and with the calibration, unless its chain errs as a whole (every submap of it
// beyond its covariance: a sensor's bias, a chain the calibration weighs down below), which the
// first pass cannot mend and would meet at every join: the check is made again under the
// variance factors the residuals give. A wrong pairing stands out of its chain's factor (one
// submap's chi-square some 15 times its mean).
bool NetworkJoin::StandsOnStartFrames() {
  judged_excess_.clear();
  bool spared = false;
  if (!Beyond(second_.net.Excesses(), &spared, &judged_excess_)) {
    out_.recheck_spared = spared;
    return true;
  }
  if (options_.calibrate_sigmas > 0) {
    std::vector<double> weights(order_.size(), 1.0);
    bool spared_weighted = false;
    if (second_.net.Calibrate(options_.calibrate_sigmas, &weights) &&
        !Beyond(second_.net.Excesses(&weights), &spared_weighted, nullptr)) {
      out_.recheck_spared = spared_weighted;
      return true;
    }
  }
  return false;
}

// The pairings between chains that entered whose two references the join keeps apart.
void NetworkJoin::CountDroppedTies() {
  std::vector<bool> entered(chains_.size(), false);
  for (std::size_t c : order_) entered[c] = true;
  out_.ties_dropped = 0;
  for (const Tie& t : ties_) {
    const std::size_t ca = chain_of_slot_[static_cast<std::size_t>(t.a)];
    const std::size_t cb = chain_of_slot_[static_cast<std::size_t>(t.b)];
    if (entered[ca] && entered[cb] && unions_.Find(t.a) != unions_.Find(t.b)) ++out_.ties_dropped;
  }
}

// Each chain's information calibrated by its residuals (a variance factor per chain, estimated
// as variance components are: chi-square over redundancy, reweighted until none is beyond what
// chance gives it): a chain whose sensors err beyond their model weighs less. Returns per chain
// in order 1 / its variance factor.
std::vector<double> NetworkJoin::Calibrate() {
  int calibrations = 0;
  std::vector<double> weights(order_.size(), 1.0);
  if (options_.calibrate_sigmas > 0) {
    for (int round = 0; round < options_.max_calibrations; ++round) {
      if (!second_.net.Calibrate(options_.calibrate_sigmas, &weights)) break;
      std::vector<std::vector<Pose2>> frames = second_.net.frames;
      std::map<int, Eigen::Vector2d> start;
      for (int slot : second_.net.held) start[slot] = second_.net.At(slot);
      second_ = Solve(chains_, order_, landmark_of_, refs_.size(), {}, 1.0, RobustKernel{}, &frames, &start,
                      options_.max_iterations, info_, &eq_, &weights);
      ++calibrations;
    }
  }
  out_.calibrations = calibrations;
  return weights;
}

// The landmarks with their marginals, each chain's frames, and each caller group's landmark: the
// landmark of its first reference in chain order that entered.
void NetworkJoin::Result(const std::map<LandmarkRef, int>& groups) {
  std::vector<int> wanted, wanted_slots;
  for (int slot : second_.net.held) {
    wanted.push_back(second_.net.slot_var[static_cast<std::size_t>(slot)]);
    wanted_slots.push_back(slot);
  }
  const std::vector<Eigen::MatrixXd> marginals = eq_->Marginals(wanted);
  if (marginals.size() != wanted.size()) return;
  out_.solved = true;
  std::map<int, int> index_of;  // landmark slot -> place in out_.landmarks
  for (std::size_t i = 0; i < wanted_slots.size(); ++i) {
    NetworkLandmark l;
    l.mean = second_.net.At(wanted_slots[i]);
    l.cov = marginals[i];
    index_of[wanted_slots[i]] = static_cast<int>(out_.landmarks.size());
    out_.landmarks.push_back(std::move(l));
  }
  for (std::size_t i = 0; i < order_.size(); ++i) {
    const ChainInput& c = chains_[order_[i]];
    out_.joined[order_[i]] = true;
    out_.origins[order_[i]] = second_.net.frames[i][0];
    out_.frames[order_[i]] = second_.net.frames[i];
    out_.submaps += static_cast<int>(c.submaps.size());
    std::set<std::uint32_t> keys;
    for (const WireSubmap* s : c.submaps) keys.insert(s->keys.begin(), s->keys.end());
    for (std::uint32_t key : keys) {
      const LandmarkRef ref{c.robot, c.incarnation, key};
      out_.landmarks[static_cast<std::size_t>(index_of.at(landmark_of_.at(ref)))].refs.push_back(ref);
    }
  }
  for (const auto& [ref, g] : groups) {
    const auto l = landmark_of_.find(ref);
    if (l == landmark_of_.end()) continue;
    const auto i = index_of.find(l->second);
    if (i == index_of.end()) continue;
    int& slot = out_.of_group[static_cast<std::size_t>(g)];
    const auto held = [&](int index) {
      const NetworkLandmark& lm = out_.landmarks[static_cast<std::size_t>(index)];
      for (std::size_t c : order_) {
        for (const LandmarkRef& r : lm.refs) {
          if (r.robot == chains_[c].robot && r.incarnation == chains_[c].incarnation) return c;
        }
      }
      return chains_.size();
    };
    if (slot < 0 || held(i->second) < held(slot)) slot = i->second;
  }
}

NetworkResult NetworkJoin::Run(const std::map<LandmarkRef, int>& groups) {
  out_.joined.assign(chains_.size(), false);
  out_.frames.assign(chains_.size(), {});
  out_.origins.reserve(chains_.size());
  for (const ChainInput& c : chains_) out_.origins.push_back(c.origin);
  int caller_groups = 0;
  for (const auto& [ref, g] : groups) caller_groups = std::max(caller_groups, g + 1);
  out_.of_group.assign(static_cast<std::size_t>(caller_groups), -1);
  if (chains_.empty()) return std::move(out_);
  IndexSlots();
  if (!wellformed_[0]) return std::move(out_);
  OfferTies(groups);

  const std::vector<std::size_t> first_order = Enter(ties_);
  const RobustKernel first_kernel{RobustLoss::kCauchy, options_.tie_cauchy};
  PlaceNewChainsAlone(first_order, first_kernel);
  // Whether the pairings may be judged on the start frames: every chain to enter has them.
  const bool on_start_frames = options_.judge_on_start_frames &&
                               std::all_of(first_order.begin(), first_order.end(),
                                           [&](std::size_t c) { return !chains_[c].start_frames.empty(); });
  std::map<LandmarkRef, int> judged_landmarks;  // a join judged on the start frames and refused: its landmarks
  for (bool rechecking = false;; rechecking = true) {
    // The pairings judged: by the first pass (every reference its own landmark, the pairings
    // soft ties under Cauchy's kernel), or on the start frames. `at` is the network they were
    // judged on: where the exact join starts.
    const bool first_pass = !on_start_frames || rechecking;
    if (first_pass) {
      first_ = Solve(chains_, first_order, slot_of_, refs_.size(), ties_, options_.tie_sigma_m, first_kernel, nullptr,
                     nullptr, options_.max_iterations, info_, &eq_);
    } else {
      first_ = Solved{Place(chains_, first_order, slot_of_, refs_.size(), ties_, nullptr, nullptr, info_), {}};
    }
    const Network& at = first_.net;
    // Second pass: the exact join, each union one landmark, from where the pairings were judged.
    order_ = Enter(KeepTies(at));  // those of the first pass, or fewer
    landmark_of_.clear();
    for (const auto& [ref, slot] : slot_of_) landmark_of_[ref] = unions_.Find(slot);
    std::map<int, Eigen::Vector2d> start = UnionStarts(at, first_pass);
    // The judged network's frames, for the chains that enter again (by their place in its order).
    std::vector<std::vector<Pose2>> frames;
    for (std::size_t c : order_) {
      const auto i = std::find(first_order.begin(), first_order.end(), c) - first_order.begin();
      frames.push_back(at.frames[static_cast<std::size_t>(i)]);
    }
    second_ = Solve(chains_, order_, landmark_of_, refs_.size(), {}, 1.0, RobustKernel{}, &frames, &start,
                    options_.max_iterations, info_, &eq_);
    out_.first_pass = first_pass;
    out_.rechecked = rechecking;
    if (rechecking) {
      // The recheck kept the pairings the start frames had: the excesses were the submaps' own.
      out_.recheck_unchanged = landmark_of_ == judged_landmarks;
      if (out_.recheck_unchanged && memo_ != nullptr) {
        for (const auto& [id, excess] : judged_excess_) memo_->Clear(id, excess);
      }
      break;
    }
    if (first_pass || StandsOnStartFrames()) break;
    judged_landmarks = landmark_of_;
  }
  CountDroppedTies();
  if (memo_ != nullptr) {
    std::set<SubmapId> ids;
    for (const Factor& f : second_.net.factors) ids.insert(f.id);
    memo_->KeepOnly(ids);
  }
  const std::vector<double> weights = Calibrate();
  out_.variance_factors.assign(chains_.size(), 1.0);
  for (std::size_t i = 0; i < order_.size(); ++i) out_.variance_factors[order_[i]] = 1.0 / weights[i];
  info_.Sweep();
  out_.iterations = first_.report.iterations + second_.report.iterations;
  out_.converged = second_.report.converged;
  out_.cost = second_.report.final_cost;
  Result(groups);
  return std::move(out_);
}

}  // namespace

const Eigen::MatrixXd& SubmapInformation::Of(const WireSubmap& s) {
  Entry& e = entries_[s.id];
  e.used = true;
  if (e.l.rows() != s.l.rows() || e.l != s.l) {
    const auto n = s.l.rows();
    const Eigen::MatrixXd inv = s.l.triangularView<Eigen::Lower>().solve(Eigen::MatrixXd::Identity(n, n));
    e.info.noalias() = inv.transpose() * inv;
    e.l = s.l;
    ++computed_;
  }
  return e.info;
}

void SubmapInformation::Sweep() {
  for (auto it = entries_.begin(); it != entries_.end();) {
    if (!it->second.used) {
      it = entries_.erase(it);
    } else {
      it->second.used = false;
      ++it;
    }
  }
}

double RecheckMemo::Cleared(const SubmapId& id) const {
  const auto it = cleared_.find(id);
  return it == cleared_.end() ? -std::numeric_limits<double>::infinity() : it->second;
}

void RecheckMemo::KeepOnly(const std::set<SubmapId>& ids) {
  for (auto it = cleared_.begin(); it != cleared_.end();)
    it = ids.contains(it->first) ? std::next(it) : cleared_.erase(it);
}

NetworkResult JoinSubmapNetwork(std::span<const ChainInput> chains, const std::map<LandmarkRef, int>& groups,
                                const NetworkOptions& options, SubmapInformation* information, RecheckMemo* memo) {
  SubmapInformation own_information;
  NetworkJoin join(chains, options, information != nullptr ? *information : own_information, memo);
  return join.Run(groups);
}

}  // namespace mapmesh
