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

GateVerdict RadioGate::Admit(RobotId sender, std::size_t bytes, double stamp) {
  if (!InRange(sender)) return GateVerdict::kOutOfRange;
  if (options_.loss_probability > 0.0) {
    std::bernoulli_distribution lost(options_.loss_probability);
    if (lost(rng_)) return GateVerdict::kLost;
  }
  if (options_.bandwidth_bytes_per_s > 0.0) {
    double& busy = busy_until_[sender];
    if (stamp < busy) return GateVerdict::kBusy;
    busy = stamp + static_cast<double>(bytes) / options_.bandwidth_bytes_per_s;
  }
  return GateVerdict::kPass;
}

}  // namespace mapmesh
