#include "agent/radio_gate.h"

namespace mapmesh {

RadioGate::RadioGate(RobotId self, const RadioGateOptions& options, std::uint64_t seed)
    : self_(self), options_(options), rng_(seed) {}

void RadioGate::UpdateLinks(const RadioLinks& links) {
  if (links.stamp < stamp_) return;
  stamp_ = links.stamp;
  neighbours_.clear();
  for (const Link& l : links.links) {
    if (l.a == self_) neighbours_.insert(l.b);
    if (l.b == self_) neighbours_.insert(l.a);
  }
}

GateVerdict RadioGate::Admit(RobotId sender) {
  if (!InRange(sender)) return GateVerdict::kOutOfRange;
  if (options_.loss_probability > 0.0) {
    std::bernoulli_distribution lost(options_.loss_probability);
    if (lost(rng_)) return GateVerdict::kLost;
  }
  return GateVerdict::kPass;
}

}  // namespace mapmesh
