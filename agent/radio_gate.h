#pragma once
// Emulates a range-limited, lossy radio on one host: a peer's message passes only when the
// latest link table says the two robots can hear each other, and then survives a seeded
// Bernoulli loss draw. Estimation never uses the links.

#include <cstdint>
#include <random>
#include <unordered_set>

#include "common/types/messages.h"

namespace mapmesh {

struct RadioGateOptions {
  double loss_probability = 0.0;  // chance that a message in range is dropped anyway
};

enum class GateVerdict { kPass, kOutOfRange, kLost };

class RadioGate {
 public:
  RadioGate(RobotId self, const RadioGateOptions& options, std::uint64_t seed);

  // Replaces the link table (messages with an older stamp are ignored).
  void UpdateLinks(const RadioLinks& links);
  // Decides the fate of one message from `sender`. Before any table arrives, nobody is in range.
  GateVerdict Admit(RobotId sender);
  // True when the latest table links self and peer.
  bool InRange(RobotId peer) const { return neighbours_.count(peer) > 0; }
  double links_stamp() const { return stamp_; }

 private:
  RobotId self_;
  RadioGateOptions options_;
  std::mt19937_64 rng_;
  double stamp_ = -1.0;
  std::unordered_set<RobotId> neighbours_;
};

}  // namespace mapmesh
