#include "agent/fusion_backend.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <optional>
#include <random>
#include <set>
#include <span>

#include "agent/peer_schedule.h"
#include "agent/relay_policy.h"
#include "common/merge/chain_map.h"
#include "common/merge/map_alignment.h"
#include "common/merge/map_joining.h"
#include "common/merge/submap_network.h"
#include "common/merge/submap_placement.h"
#include "common/solver/chi2.h"

namespace mapmesh {
namespace {

// The cloned global map (thesis 2.3.2): each source's landmarks associated with the map's and
// fused by Covariance Intersection (or the estimator options.method names).
// Given the submaps the agent holds (agent.ci_placement piecewise), each aligned peer's map whose
// closed submaps it holds enters as its submaps, each placed on its own against the own local
// map (submap_placement.h); relayed global maps enter whole.
class CloneFusion : public FusionBackend {
 public:
  CloneFusion(RobotId self, std::uint32_t incarnation, const GlobalMapOptions& options)
      : self_(self), incarnation_(incarnation), options_(options) {}
  Built Build(const LandmarkMap& own_local, const std::vector<MapSource>& sources, const std::vector<MapSource>& direct,
              const SubmapInputs& submaps) override {
    Built b;
    if (submaps.book == nullptr) {
      b.global = BuildGlobalMap(own_local, self_, sources, options_, incarnation_, &global_memo_);
      b.published = BuildGlobalMap(own_local, self_, direct, options_, incarnation_, &published_memo_);
      return b;
    }
    // A peer is in both lists when its own map is used (not a relay of it): placed once.
    std::map<std::pair<RobotId, std::uint32_t>, std::pair<const MapSource*, std::vector<MapSource>>> placed;
    const auto piecewise = [&](const std::vector<MapSource>& in) {
      std::vector<MapSource> out;
      for (const MapSource& s : in) {
        if (s.relayed) {
          out.push_back(s);
          continue;
        }
        auto& [from, pieces] = placed[{s.robot, s.incarnation}];
        if (from == nullptr || !SamePlacedMap(*from, s)) {
          from = &s;
          pieces = Pieces(own_local, s, *submaps.book, &b.piecewise);
        }
        out.insert(out.end(), pieces.begin(), pieces.end());
      }
      return out;
    };
    b.global = BuildGlobalMap(own_local, self_, piecewise(sources), options_, incarnation_, &global_memo_);
    b.published = BuildGlobalMap(own_local, self_, piecewise(direct), options_, incarnation_, &published_memo_);
    return b;
  }

 private:
  static bool SamePlacedMap(const MapSource& a, const MapSource& b) {
    return a.to_own.Vector() == b.to_own.Vector() && a.to_own_cov == b.to_own_cov &&
           std::equal(a.map.landmarks.begin(), a.map.landmarks.end(), b.map.landmarks.begin(), b.map.landmarks.end(),
                      [](const Landmark& x, const Landmark& y) {
                        return x.id == y.id && x.mean == y.mean && x.cov == y.cov && x.signature == y.signature;
                      });
  }
  // Peer map s as its closed submaps placed on their own, then the landmarks none holds (s
  // whole when the agent holds none of its chain).
  static std::vector<MapSource> Pieces(const LandmarkMap& own_local, const MapSource& s, const SubmapBook& book,
                                       PiecewiseStats* stats) {
    std::vector<const WireSubmap*> chain;
    const std::uint32_t n = book.ChainLength(s.robot, s.incarnation);
    for (std::uint32_t i = 0; i < n; ++i) chain.push_back(book.Find({s.robot, s.incarnation, i}));
    return PlaceSubmapsPiecewise(own_local, s, chain, {}, stats);
  }

  RobotId self_;
  std::uint32_t incarnation_;
  GlobalMapOptions options_;
  AssociationMemo global_memo_, published_memo_;  // each map's ambiguous groups, from its last build
};

// Least-squares joining of the one-hop local maps only (map_joining.h: each robot's
// measurements enter once); the gates of a CI build give the association. Relays are not used:
// a relayed global map mixes information of unknown origin.
class JoiningFusion : public FusionBackend {
 public:
  JoiningFusion(RobotId self, std::uint32_t incarnation, const ExchangeOptions& options, std::uint64_t seed)
      : self_(self),
        incarnation_(incarnation),
        association_(options.global),
        options_(options),
        relay_(options),
        seed_(seed) {
    association_.method = FusionMethod::kCiConstant;
  }
  Built Build(const LandmarkMap& own_local, const std::vector<MapSource>&, const std::vector<MapSource>& direct,
              const SubmapInputs& submaps) override {
    Built b;
    if (submaps.book != nullptr && (submaps.own_open || submaps.book->ChainLength(self_, incarnation_) > 0)) {
      // A chain whose measurements a later incarnation of its robot maps again is left out.
      std::vector<const WireSubmap*> open = {submaps.own_open};
      if (submaps.peers_open != nullptr) {
        for (const auto& [key, s] : *submaps.peers_open) open.push_back(&s);
      }
      superseded_ = submaps.book->Superseded(open, submaps.heard);
      std::set<std::pair<RobotId, std::uint32_t>> held;
      for (const WireSubmap* o : open) {
        if (o != nullptr) held.insert({o->id.robot, o->id.incarnation});
      }
      for (const SubmapChain& c : submaps.book->Chains()) {
        if (c.count > 0) held.insert({c.robot, c.incarnation});
      }
      report_.chains_held = static_cast<int>(held.size());
      report_.superseded_chains = static_cast<int>(superseded_.size());
      std::vector<MapSource> inputs = direct;
      ExtendByChains(submaps, &inputs);
      PlaceRelayedChains(own_local, submaps, &inputs);
      const GlobalMap associated = BuildGlobalMap(own_local, self_, inputs, association_, incarnation_, &memo_);
      b.global = JoinChains(associated, inputs, submaps);
      // Where the chains lie as the last solve put them (each chain's first frame), for the peers.
      for (const auto& [chain, frames] : last_frames_) {
        if (chain == std::pair{self_, incarnation_} || frames.empty()) continue;
        b.placements.push_back({chain.first, chain.second, frames.front().x, frames.front().y, frames.front().theta});
      }
    } else {
      const GlobalMap associated = BuildGlobalMap(own_local, self_, direct, association_, incarnation_, &memo_);
      b.global = JoinMaps(own_local, self_, incarnation_, direct, associated);
    }
    b.published = b.global;
    b.joining = report_;
    return b;
  }

 private:
  // The submap chains joined (submap_network.h): the own chain (closed submaps, then the open
  // one) in the own frame, and each source's (an aligned peer's or a placed relayed chain's
  // closed submaps, then the latest open one taken, the publisher's or relayed, where it
  // continues them) from where the source lies, the association
  // from the CI build's groups (JoinedMap: the map it makes).
  GlobalMap JoinChains(const GlobalMap& associated, const std::vector<MapSource>& sources,
                       const SubmapInputs& submaps) {
    const SubmapBook& book = *submaps.book;
    // Per chain: the closed submaps its summary stands for, where one enters (ChainOf).
    std::map<std::pair<RobotId, std::uint32_t>, std::uint32_t> summarised;
    auto chain = [&](RobotId robot, std::uint32_t incarnation, const Pose2& origin) {
      return ChainOf(book, robot, incarnation, origin, &summarised[{robot, incarnation}]);
    };
    std::vector<ChainInput> chains = {chain(self_, incarnation_, Pose2{})};
    std::vector<bool> ends_open = {false};  // per chain: whether its last submap is an open one
    // Submaps in a chain's list: a summary stands for summarised of them.
    const auto entered = [&](const ChainInput& c) {
      const std::uint32_t s = summarised[{c.robot, c.incarnation}];
      return c.submaps.size() + (s == 0 ? 0 : s - 1);
    };
    if (submaps.own_open && submaps.own_open->id.index == entered(chains[0])) {
      chains[0].submaps.push_back(submaps.own_open);  // it continues the chain (none is missing before it)
      ends_open[0] = true;
    }
    for (const MapSource& s : sources) {
      if (superseded_.contains({s.robot, s.incarnation})) continue;
      ChainInput c = chain(s.robot, s.incarnation, s.to_own);
      bool open_last = false;
      if (submaps.peers_open != nullptr) {
        const auto open = submaps.peers_open->find({s.robot, s.incarnation});
        if (open != submaps.peers_open->end() && open->second.id.index == entered(c)) {
          c.submaps.push_back(&open->second);
          open_last = true;
        }
      }
      if (!c.submaps.empty()) {
        chains.push_back(std::move(c));
        ends_open.push_back(open_last);
      }
    }
    std::map<LandmarkRef, int> groups;
    for (std::size_t g = 0; g < associated.origins.size(); ++g) {
      for (const LandmarkOrigin& o : associated.origins[g])
        groups[{o.robot, o.incarnation, o.id}] = static_cast<int>(g);
    }
    // Each chain starts where the last solve left it: the chains change little from one period
    // to the next.
    for (ChainInput& c : chains) {
      const auto it = last_frames_.find({c.robot, c.incarnation});
      if (it != last_frames_.end()) {
        const auto then = last_summarised_.find({c.robot, c.incarnation});
        c.start_frames = Renumbered(it->second, then == last_summarised_.end() ? 0 : then->second,
                                    summarised[{c.robot, c.incarnation}]);
      }
      const auto l = last_landmarks_.find({c.robot, c.incarnation});
      if (l != last_landmarks_.end()) c.start_landmarks = l->second;
    }
    NetworkOptions network;
    network.calibrate_sigmas = options_.join_calibrate_sigmas;
    const NetworkResult r = JoinSubmapNetwork(chains, groups, network, &information_, &recheck_memo_);
    if (r.solved) {
      last_frames_.clear();
      last_summarised_ = summarised;
      for (std::size_t i = 0; i < chains.size(); ++i) {
        if (!r.joined[i]) continue;
        std::vector<Pose2>& frames = last_frames_[{chains[i].robot, chains[i].incarnation}] = r.frames[i];
        // An open submap ends where its robot was: by the next solve it has moved on, and its end
        // is composed along the open submap then.
        if (ends_open[i]) frames.pop_back();
      }
      last_landmarks_.clear();
      for (const NetworkLandmark& l : r.landmarks) {
        for (const LandmarkRef& ref : l.refs) last_landmarks_[{ref.robot, ref.incarnation}][ref.key] = l.mean;
      }
    }
    report_.chains = static_cast<int>(chains.size());
    report_.chains_joined = static_cast<int>(std::count(r.joined.begin(), r.joined.end(), true));
    // The sources the join leaves to the CI build: no submaps held, or a chain not joined.
    std::set<std::pair<RobotId, std::uint32_t>> in_join;
    for (std::size_t i = 0; i < chains.size(); ++i) {
      if (r.solved && r.joined[i]) in_join.insert({chains[i].robot, chains[i].incarnation});
    }
    report_.sources_by_ci = static_cast<int>(std::count_if(sources.begin(), sources.end(), [&](const MapSource& s) {
      return !superseded_.contains({s.robot, s.incarnation}) && !in_join.contains({s.robot, s.incarnation});
    }));
    report_.submaps = r.submaps;
    report_.submaps_summarised = 0;
    for (std::size_t i = 0; i < chains.size(); ++i) {
      const std::uint32_t s = summarised[{chains[i].robot, chains[i].incarnation}];
      if (!r.joined[i] || s == 0) continue;
      report_.submaps += static_cast<int>(s) - 1;  // the summary counted once
      report_.submaps_summarised += static_cast<int>(s);
    }
    report_.iterations = r.iterations;
    report_.converged = r.converged;
    report_.solved = r.solved;
    report_.ties = r.ties;
    report_.ties_dropped = r.ties_dropped;
    report_.first_passes += r.first_pass ? 1 : 0;
    report_.placed_alone += r.placed_alone > 0 ? 1 : 0;
    report_.calibrated_solves += r.calibrations > 0 ? 1 : 0;
    report_.chains_calibrated = static_cast<int>(std::count_if(r.variance_factors.begin(), r.variance_factors.end(),
                                                               [](double f) { return f > 1.0; }));
    report_.worst_variance_factor = r.variance_factors.empty()
                                        ? 1.0
                                        : *std::max_element(r.variance_factors.begin(), r.variance_factors.end());
    report_.rechecks += r.rechecked ? 1 : 0;
    report_.rechecks_unchanged += r.recheck_unchanged ? 1 : 0;
    report_.rechecks_spared += r.recheck_spared ? 1 : 0;
    ++report_.solves;
    if (!r.solved) return associated;
    return JoinedMap(associated, r, chains, association_.gate_probability);
  }

  // A chain's input: its closed submaps as held (the open one is the caller's), all but the last
  // network_window of them as one summary (their chain's own join: ChainMap::Summary) where
  // two or more would be, so that a join's size is bounded by the map's, not by the run's
  // length; *summarised: the submaps the summary stands for (0: none).
  ChainInput ChainOf(const SubmapBook& book, RobotId robot, std::uint32_t incarnation, const Pose2& origin,
                     std::uint32_t* summarised) {
    ChainInput c{robot, incarnation, {}, origin, {}, {}};
    const std::uint32_t n = book.ChainLength(robot, incarnation);
    std::vector<const WireSubmap*> closed;
    for (std::uint32_t i = 0; i < n; ++i) closed.push_back(book.Find({robot, incarnation, i}));
    const auto window = static_cast<std::uint32_t>(options_.network_window);
    *summarised = 0;
    const auto kept = summaries_.find({robot, incarnation});
    if (kept != summaries_.end() && kept->second.joined() + window > n) summaries_.erase(kept);  // the chain shrank
    if (n >= window + 2) {
      ChainMap& m = summaries_.try_emplace({robot, incarnation}, options_.chain_join).first->second;
      m.Extend(std::span(closed).first(n - window));
      const WireSubmap* summary = m.joined() > 1 ? m.Summary(*closed[m.joined() - 1]) : nullptr;
      if (summary != nullptr) {
        c.submaps.push_back(summary);
        *summarised = static_cast<std::uint32_t>(m.joined());
      }
    }
    c.submaps.insert(c.submaps.end(), closed.begin() + *summarised, closed.end());
    return c;
  }

  // A chain's frames as a solve left them, with a summary of its first `then` submaps (0: none),
  // renumbered for one of its first `now`: frame j > 0 is X_{j + s - 1} with a summary of s > 0
  // submaps, else X_j (the frames within a summary are not in the list). Its first frame alone
  // when the summary shrank.
  static std::vector<Pose2> Renumbered(const std::vector<Pose2>& frames, std::uint32_t then, std::uint32_t now) {
    if (frames.empty()) return {};
    const auto base = [](std::uint32_t s) { return s == 0 ? 0u : s - 1; };
    if (now < then) return {frames.front()};
    const std::size_t gone = base(now) - base(then);
    std::vector<Pose2> out = {frames.front()};
    if (frames.size() > gone + 1)
      out.insert(out.end(), frames.begin() + 1 + static_cast<std::ptrdiff_t>(gone), frames.end());
    return out;
  }

  // The global map of a solved join: each association group a joined chain holds as the join
  // estimated it, its origins the references the join merged (and those of sources it did not
  // join); each of the join's landmarks no group names (a pairing the submaps contradicted split
  // it off its group, or it is in no map the association had) appended, so that what the join
  // dropped from a group is not lost from the map, unless the association's gate would pair it
  // with a landmark of the map (the join says they differ, the gate that they may be one: one
  // copy, not two); the rest as the CI build has them.
  static GlobalMap JoinedMap(const GlobalMap& associated, const NetworkResult& r, const std::vector<ChainInput>& chains,
                             double gate_probability) {
    std::set<std::pair<RobotId, std::uint32_t>> joined;
    for (std::size_t i = 0; i < chains.size(); ++i) {
      if (r.joined[i]) joined.insert({chains[i].robot, chains[i].incarnation});
    }
    const auto origins_of = [](const NetworkLandmark& l) {
      std::vector<LandmarkOrigin> o;
      for (const LandmarkRef& ref : l.refs) o.push_back({ref.robot, ref.incarnation, ref.key, false});
      return o;
    };
    GlobalMap out = associated;
    std::vector<bool> placed(r.landmarks.size(), false);
    for (std::size_t g = 0; g < out.map.landmarks.size(); ++g) {
      const int at = g < r.of_group.size() ? r.of_group[g] : -1;
      if (at < 0) continue;
      const NetworkLandmark& l = r.landmarks[static_cast<std::size_t>(at)];
      placed[static_cast<std::size_t>(at)] = true;
      out.map.landmarks[g].mean = l.mean;
      out.map.landmarks[g].cov = l.cov;
      std::vector<LandmarkOrigin> origins = origins_of(l);
      for (const LandmarkOrigin& o : associated.origins[g]) {
        if (o.relayed || !joined.contains({o.robot, o.incarnation})) origins.push_back(o);
      }
      out.origins[g] = std::move(origins);
    }
    const std::size_t grouped = out.map.landmarks.size();
    const double gate = Chi2Quantile(gate_probability, 2);
    const auto near_one = [&](const NetworkLandmark& x) {
      for (std::size_t g = 0; g < grouped; ++g) {
        const Landmark& y = out.map.landmarks[g];
        const Eigen::Vector2d d = x.mean - y.mean;
        if (d.dot((x.cov + y.cov).ldlt().solve(d)) < gate) return true;
      }
      return false;
    };
    for (std::size_t i = 0; i < r.landmarks.size(); ++i) {
      if (placed[i] || near_one(r.landmarks[i])) continue;
      Landmark l;
      l.id = static_cast<std::uint32_t>(out.map.landmarks.size());
      l.mean = r.landmarks[i].mean;
      l.cov = r.landmarks[i].cov;
      out.map.landmarks.push_back(l);
      out.origins.push_back(origins_of(r.landmarks[i]));
    }
    return out;
  }

  // The chains of which the agent holds closed submaps, and those of which it holds only an
  // open submap that begins them (a robot heard through others before its first submap
  // closed), in (robot, incarnation) order.
  static std::vector<SubmapChain> HeldChains(const SubmapInputs& submaps) {
    std::vector<SubmapChain> held;
    for (const SubmapChain& c : submaps.book->Chains()) {
      if (c.count > 0) held.push_back(c);
    }
    const std::size_t closed = held.size();
    if (submaps.peers_open != nullptr) {
      for (const auto& [key, open] : *submaps.peers_open) {
        const bool has_closed = std::any_of(held.begin(), held.begin() + static_cast<std::ptrdiff_t>(closed),
                                            [&](const SubmapChain& c) {
                                              return PeerKey{c.robot, c.incarnation} == key;
                                            });
        if (!has_closed && open.id.index == 0) held.push_back({open.id.robot, open.id.incarnation, 0});
      }
    }
    std::sort(held.begin(), held.end(), [](const SubmapChain& a, const SubmapChain& b) {
      return std::pair{a.robot, a.incarnation} < std::pair{b.robot, b.incarnation};
    });
    return held;
  }

  // The latest open submap taken of a chain (null for none).
  static const WireSubmap* OpenOf(const SubmapInputs& submaps, const std::pair<RobotId, std::uint32_t>& chain) {
    if (submaps.peers_open == nullptr) return nullptr;
    const auto o = submaps.peers_open->find({chain.first, chain.second});
    return o == submaps.peers_open->end() ? nullptr : &o->second;
  }

  // A one-hop peer's map as its chain holds it, where the chain has gone on past the map: a peer
  // that fell silent (out of range, or gone) keeps the last map taken from it, while its later
  // submaps still reach the agent through relays. Their landmarks would be joined but in no
  // association group, and so in no global landmark: the map is rebuilt from the chain (its
  // closed submaps, then the open one where it continues them, as a relayed chain's), in the
  // same frame, with any landmark of the last map the chain lacks kept. A map that holds every
  // landmark of its chain is used as it is.
  void ExtendByChains(const SubmapInputs& submaps, std::vector<MapSource>* inputs) {
    const SubmapBook& book = *submaps.book;
    report_.chains_extended = 0;
    for (MapSource& s : *inputs) {
      const std::pair key{s.robot, s.incarnation};
      if (superseded_.contains(key)) continue;
      std::vector<std::uint32_t> ids;
      ids.reserve(s.map.size());
      for (const Landmark& l : s.map.landmarks) ids.push_back(l.id);
      std::sort(ids.begin(), ids.end());
      const auto beyond = [&](const WireSubmap& w) {
        return std::any_of(w.keys.begin(), w.keys.end(),
                           [&](std::uint32_t k) { return !std::binary_search(ids.begin(), ids.end(), k); });
      };
      std::vector<const WireSubmap*> chain;
      bool past = false;
      for (std::uint32_t i = 0; i < book.ChainLength(s.robot, s.incarnation); ++i) {
        chain.push_back(book.Find({s.robot, s.incarnation, i}));
        past = past || beyond(*chain.back());
      }
      const WireSubmap* open = OpenOf(submaps, key);
      if (open != nullptr && open->id.index == chain.size()) past = past || beyond(*open);
      if (!past) continue;
      ChainMap& m = direct_chains_.try_emplace(key, options_.chain_join).first->second;
      m.Extend(chain);
      if (m.broken() || m.joined() != chain.size()) continue;
      LandmarkMap rebuilt = m.MapWith(open);
      std::vector<std::uint32_t> held;
      for (const Landmark& l : rebuilt.landmarks) held.push_back(l.id);
      std::sort(held.begin(), held.end());
      for (const Landmark& l : s.map.landmarks) {
        if (!std::binary_search(held.begin(), held.end(), l.id)) rebuilt.landmarks.push_back(l);
      }
      s.map = std::move(rebuilt);
      ++report_.chains_extended;
    }
  }

  // A chain held only through relays: its map rebuilt from its submaps, and where it lies.
  struct Relayed {
    explicit Relayed(const JoinerOptions& o) : map(o) {}
    ChainMap map;
    std::optional<AlignmentResult> candidate;              // an alignment waiting for a later one to agree
    std::optional<Pose2> to_own;                           // placed: where the chain's first frame lies ...
    Eigen::Matrix3d to_own_cov = Eigen::Matrix3d::Zero();  // ... and how well the alignment knew it
    RelayedAlignmentFacts tried;                           // its alignments so far (peer_schedule.h)
    std::uint64_t attempts = 0;
    std::set<PeerKey> offered_by;  // the peers whose placements of it were verified at the last try
  };

  // An aligned peer's placement of a chain, composed with where we put the peer.
  struct Offer {
    PeerKey by;
    Pose2 to_own;
  };

  // Appends to `inputs` (the one-hop maps) a source for every placed chain the agent holds only
  // through relays, in (robot, incarnation) order. A chain is placed where an aligned peer's
  // last join put it (composed with where ours put that peer), once the maps verify it there
  // (VerifyAlignment against the global map of the own map and the sources before it), trying
  // the peers in order; else by aligning its rebuilt map against that global map, once a later
  // alignment agrees with the first (relay tolerances at the chain map's centroid); a
  // disagreeing one replaces the candidate. An alignment is tried again when either map has
  // grown by retry_growth, or align_period_s after an accepted one (the same maps, another
  // draw): a failed one on the same maps would fail again. Both double after a failed one
  // (RelayedAlignmentDue). A peer's placement is verified at once when the peer did not offer
  // one at the last try. Once placed, the chain lies where the last solve put its first frame.
  void PlaceRelayedChains(const LandmarkMap& own_local, const SubmapInputs& submaps, std::vector<MapSource>* inputs) {
    const SubmapBook& book = *submaps.book;
    std::set<std::pair<RobotId, std::uint32_t>> heard = {{self_, incarnation_}};
    for (const MapSource& s : *inputs) heard.insert({s.robot, s.incarnation});
    const std::size_t direct = inputs->size();
    report_.relayed_chains = report_.relayed_placed = 0;
    std::optional<LandmarkMap> target;  // the own and placed maps, built when an unplaced chain needs it
    for (const SubmapChain& c : HeldChains(submaps)) {
      if (heard.count({c.robot, c.incarnation}) != 0 || superseded_.contains({c.robot, c.incarnation})) continue;
      ++report_.relayed_chains;
      Relayed& r = relayed_.try_emplace({c.robot, c.incarnation}, options_.chain_join).first->second;
      std::vector<const WireSubmap*> chain;
      for (std::uint32_t i = 0; i < c.count; ++i) chain.push_back(book.Find({c.robot, c.incarnation, i}));
      r.map.Extend(chain);
      // Aligned and verified on its closed submaps (the open one of a robot heard through others
      // changes as it is relayed again), or on its open one where it holds none.
      const LandmarkMap& theirs = c.count > 0 ? r.map.map() : r.map.MapWith(OpenOf(submaps, {c.robot, c.incarnation}));
      if (!r.to_own && theirs.size() >= 3) {
        const std::vector<Offer> offers = Offers({c.robot, c.incarnation}, std::span(inputs->data(), direct),
                                                 submaps.peers_placements);
        const bool new_offer = std::any_of(offers.begin(), offers.end(),
                                           [&](const Offer& o) { return !r.offered_by.contains(o.by); });
        if (!target) target = BuildGlobalMap(own_local, self_, *inputs, association_, incarnation_).map;
        r.tried.candidate = r.candidate.has_value();
        const bool due = RelayedAlignmentDue(r.tried, theirs.size(), target->size(), submaps.now, options_);
        if (due || new_offer) {
          r.offered_by.clear();
          for (const Offer& o : offers) r.offered_by.insert(o.by);
          if (!PlaceByOffer(r, theirs, offers, *target) && due) {
            r.tried.tried_at = submaps.now;
            Align(c, r, theirs, *target);
          }
        }
      }
      if (!r.to_own) continue;
      ++report_.relayed_placed;
      const auto last = last_frames_.find({c.robot, c.incarnation});
      const Pose2 at = last != last_frames_.end() && !last->second.empty() ? last->second.front() : *r.to_own;
      // Its landmarks as the join holds them: the open submap relayed to us too, where it
      // continues the chain (JoinChains joins it).
      const WireSubmap* open = OpenOf(submaps, {c.robot, c.incarnation});
      inputs->push_back(MapSource{c.robot, c.incarnation, r.map.MapWith(open), at, r.to_own_cov, false});
      target.reset();
    }
  }

  // The placements of chain `key` that the aligned one-hop peers (`direct`, in order) offer, each
  // composed with where we put the peer: where the last solve put its chain's first frame, else
  // its alignment.
  std::vector<Offer> Offers(const std::pair<RobotId, std::uint32_t>& key, std::span<const MapSource> direct,
                            const std::map<PeerKey, std::vector<ChainPlacement>>* placements) const {
    std::vector<Offer> offers;
    if (placements == nullptr) return offers;
    for (const MapSource& s : direct) {
      const auto held = placements->find({s.robot, s.incarnation});
      if (held == placements->end()) continue;
      const auto it = std::lower_bound(held->second.begin(), held->second.end(), key,
                                       [](const ChainPlacement& p, const std::pair<RobotId, std::uint32_t>& k) {
                                         return std::pair{p.robot, p.incarnation} < k;
                                       });
      if (it == held->second.end() || std::pair{it->robot, it->incarnation} != key) continue;
      const auto last = last_frames_.find({s.robot, s.incarnation});
      const Pose2 peer = last != last_frames_.end() && !last->second.empty() ? last->second.front() : s.to_own;
      offers.push_back({{s.robot, s.incarnation}, peer * Pose2{it->x, it->y, it->theta}});
    }
    return offers;
  }

  // Places the chain at the first offer the maps verify; false when none does.
  bool PlaceByOffer(Relayed& r, const LandmarkMap& theirs, const std::vector<Offer>& offers,
                    const LandmarkMap& target) {
    for (const Offer& o : offers) {
      const AlignmentResult a = VerifyAlignment(target, theirs, o.to_own, options_.align);
      if (!a.accepted()) {
        ++report_.placements_refused;
        continue;
      }
      r.to_own = a.transform;
      r.to_own_cov = a.cov;
      ++report_.relayed_by_placement;
      return true;
    }
    return false;
  }

  void Align(const SubmapChain& c, Relayed& r, const LandmarkMap& theirs, const LandmarkMap& target) {
    r.tried.tried_size = theirs.size();
    r.tried.tried_target = target.size();
    std::mt19937_64 rng(seed_ ^ (std::uint64_t{c.robot} * 0x9e3779b97f4a7c15ULL) ^
                        (std::uint64_t{c.incarnation} * 0xbf58476d1ce4e5b9ULL) ^
                        (++r.attempts * 0x94d049bb133111ebULL));
    ++report_.relayed_alignments;
    const AlignmentResult a = AlignMaps(target, theirs, options_.align, rng);
    if (!a.accepted()) {
      ++r.tried.failures;
      return;
    }
    r.tried.failures = 0;
    if (r.candidate && relay_.Agree(r.candidate->transform, a.transform, Centroid(theirs))) {
      r.to_own = a.transform;
      r.to_own_cov = a.cov;
      return;
    }
    if (r.candidate) ++report_.relayed_disagreements;
    r.candidate = a;
  }

  RobotId self_;
  std::uint32_t incarnation_;
  GlobalMapOptions association_;
  ExchangeOptions options_;
  RelayPolicy relay_;
  std::uint64_t seed_;
  AssociationMemo memo_;
  JoiningReport report_;
  std::map<std::pair<RobotId, std::uint32_t>, Relayed> relayed_;
  std::map<std::pair<RobotId, std::uint32_t>, ChainMap>
      direct_chains_;                                       // one-hop peers' maps past their last (ExtendByChains)
  std::set<std::pair<RobotId, std::uint32_t>> superseded_;  // at the last build (SubmapBook::Superseded)
  SubmapInformation information_;  // the submaps' information matrices, from one solve to the next
  RecheckMemo recheck_memo_;       // what the rechecks found the submaps' own, from one solve to the next
  // The last solve's frames and landmarks (by key) per chain: where the next one starts.
  std::map<std::pair<RobotId, std::uint32_t>, std::vector<Pose2>> last_frames_;
  std::map<std::pair<RobotId, std::uint32_t>, std::uint32_t> last_summarised_;  // ... and its summaries' sizes
  // Per chain: its closed submaps but the last network_window joined, whose summary enters the join.
  std::map<std::pair<RobotId, std::uint32_t>, ChainMap> summaries_;
  std::map<std::pair<RobotId, std::uint32_t>, std::map<std::uint32_t, Eigen::Vector2d>> last_landmarks_;
};

}  // namespace

std::unique_ptr<FusionBackend> MakeFusionBackend(RobotId self, std::uint32_t incarnation,
                                                 const ExchangeOptions& options, std::uint64_t seed) {
  if (options.global.method == FusionMethod::kJoining) {
    return std::make_unique<JoiningFusion>(self, incarnation, options, seed);
  }
  return std::make_unique<CloneFusion>(self, incarnation, options.global);
}

}  // namespace mapmesh
