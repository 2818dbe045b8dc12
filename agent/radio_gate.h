#pragma once
// Emulates a range-limited, lossy, bandwidth-limited radio on one host. A peer's message
// passes only when the latest link table says the two robots can hear each other; then it
// survives a seeded Bernoulli loss draw; then it must find the link free: a message of B
// bytes keeps the link from that sender busy for B / bandwidth seconds of scenario time, and
// messages arriving meanwhile are dropped (a newer map supersedes them anyway). A message that
// passes arrives after the link's latency and its own transmission time (Arrival): each link
// (an unordered pair) has its own latency, latency_s plus a uniform draw in [0,
// latency_jitter_s) that is a function of the run's seed and the pair alone, so both ends and
// every run of the scenario agree on it. Estimation never uses the links.
//
// A table's stamp must be plausible: finite, within the run, and no further than
// max_stamp_jump_s ahead of the agent's own time and of the table in use. A table that jumps
// further is held until the next table confirms it (a later stamp within the window of it);
// a table confirmed by none is refused, so one forged stamp cannot make every later table
// look old.

#include <cstdint>
#include <limits>
#include <optional>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include "common/types/messages.h"

namespace mapmesh {

struct RadioGateOptions {
  double loss_probability = 0.0;       // chance that a message in range is dropped anyway
  double bandwidth_bytes_per_s = 0.0;  // per link; 0 means unlimited
  double max_stamp_jump_s = 20.0;      // a table this far ahead of our time and the last table is held (see above)
  double max_stamp_s = std::numeric_limits<double>::infinity();  // no table is stamped after this (the run's end)
  double latency_s = 0.0;                                        // every link's latency at least ...
  double latency_jitter_s = 0.0;                                 // ... plus a uniform per-link draw in [0, this)
  std::uint64_t link_seed = 0;  // the run's seed: the per-link draws' (the same at both ends)
};

// The latency of the link between robots a and b (either order): latency_s plus the pair's
// uniform draw in [0, latency_jitter_s).
double LinkLatency(const RadioGateOptions& options, RobotId a, RobotId b);

enum class GateVerdict { kPass, kOutOfRange, kLost, kBusy };

class RadioGate {
 public:
  RadioGate(RobotId self, const RadioGateOptions& options, std::uint64_t seed);

  enum class LinksReceipt { kUsed, kOlder, kHeld, kImplausible };
  // Replaces the link table at the agent's scenario time `now` (an older table is ignored; an
  // implausible one refused or held: see above).
  LinksReceipt UpdateLinks(const RadioLinks& links, double now);
  // Uses this table whatever it is (lockstep: the exchange tick's, from the feeder).
  void SetLinks(const RadioLinks& links) {
    held_.reset();
    Use(links);
  }
  // Tables refused as implausible so far (held ones nothing confirmed included).
  std::uint32_t links_refused() const { return links_refused_; }
  // Decides the fate of one message of `bytes` from `sender` sent at scenario time `stamp`.
  // Before any table arrives, nobody is in range.
  GateVerdict Admit(RobotId sender, std::size_t bytes, double stamp);
  // When a message of `bytes` from `sender` sent at `stamp` arrives: after the link's latency
  // and its transmission time (bytes over the bandwidth, where there is one).
  double Arrival(RobotId sender, std::size_t bytes, double stamp) const;
  // Whether messages can arrive later than they were sent (a latency or a bandwidth is set).
  bool Delays() const {
    return options_.latency_s > 0.0 || options_.latency_jitter_s > 0.0 || options_.bandwidth_bytes_per_s > 0.0;
  }
  // True when the latest table links self and peer.
  bool InRange(RobotId peer) const { return neighbours_.count(peer) > 0; }
  double links_stamp() const { return stamp_; }

 private:
  RobotId self_;
  void Use(const RadioLinks& links);

  RadioGateOptions options_;
  std::mt19937_64 rng_;
  double stamp_ = -1.0;
  std::optional<RadioLinks> held_;
  std::uint32_t links_refused_ = 0;
  std::unordered_set<RobotId> neighbours_;
  std::unordered_map<RobotId, double> busy_until_;  // per sender, scenario seconds
};

}  // namespace mapmesh
