#pragma once
// Emulates a range-limited, lossy, bandwidth-limited radio on one host. A peer's message
// passes only when the latest link table says the two robots can hear each other; then it
// survives a seeded Bernoulli loss draw; then it must find the link free: a message of B
// bytes keeps the link from that sender busy for B / bandwidth seconds of scenario time, and
// messages arriving meanwhile are dropped (a newer map supersedes them anyway). Estimation
// never uses the links.

#include <cstdint>
#include <random>
#include <unordered_map>
#include <unordered_set>

#include "common/types/messages.h"

namespace mapmesh {

struct RadioGateOptions {
  double loss_probability = 0.0;      // chance that a message in range is dropped anyway
  double bandwidth_bytes_per_s = 0.0; // per link; 0 means unlimited
};

enum class GateVerdict { kPass, kOutOfRange, kLost, kBusy };

class RadioGate {
 public:
  RadioGate(RobotId self, const RadioGateOptions& options, std::uint64_t seed);

  // Replaces the link table (messages with an older stamp are ignored).
  void UpdateLinks(const RadioLinks& links);
  // Decides the fate of one message of `bytes` from `sender` sent at scenario time `stamp`.
  // Before any table arrives, nobody is in range.
  GateVerdict Admit(RobotId sender, std::size_t bytes, double stamp);
  // True when the latest table links self and peer.
  bool InRange(RobotId peer) const { return neighbours_.count(peer) > 0; }
  double links_stamp() const { return stamp_; }

 private:
  RobotId self_;
  RadioGateOptions options_;
  std::mt19937_64 rng_;
  double stamp_ = -1.0;
  std::unordered_set<RobotId> neighbours_;
  std::unordered_map<RobotId, double> busy_until_;  // per sender, scenario seconds
};

}  // namespace mapmesh
