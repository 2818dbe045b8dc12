#include "agent/radio_gate.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/types/keyed_draw.h"

namespace mapmesh {

RadioGate::RadioGate(RobotId self, const RadioGateOptions& options, std::uint64_t seed)
    : self_(self), options_(options), rng_(seed) {}

RadioGate::LinksReceipt RadioGate::UpdateLinks(const RadioLinks& links, double now) {
  if (!std::isfinite(links.stamp) || links.stamp < 0.0 || links.stamp > options_.max_stamp_s) {
    ++links_refused_;
    return LinksReceipt::kImplausible;
  }
  const double jump = options_.max_stamp_jump_s;
  if (held_) {
    const RadioLinks held = *std::exchange(held_, std::nullopt);
    if (links.stamp >= held.stamp && links.stamp <= held.stamp + jump) {
      Use(links);  // confirmed: the stream did move on
      return LinksReceipt::kUsed;
    }
    ++links_refused_;  // nothing confirmed it
  }
  if (links.stamp < stamp_) return LinksReceipt::kOlder;
  // The first table sets the clock; later ones may run ahead of it and of ours by the window.
  if (stamp_ >= 0.0 && links.stamp > std::max(stamp_, now) + jump) {
    held_ = links;
    return LinksReceipt::kHeld;
  }
  Use(links);
  return LinksReceipt::kUsed;
}

void RadioGate::Use(const RadioLinks& links) {
  stamp_ = links.stamp;
  neighbours_.clear();
  for (const Link& l : links.links) {
    if (l.a == self_) neighbours_.insert(l.b);
    if (l.b == self_) neighbours_.insert(l.a);
  }
}

double LinkLatency(const RadioGateOptions& options, RobotId a, RobotId b) {
  if (options.latency_jitter_s <= 0.0) return options.latency_s;
  constexpr std::uint64_t kLatencyStream = 3;  // the feeder's radio model draws streams 1 and 2
  const std::uint64_t key = DrawKey(options.link_seed, {kLatencyStream, std::min(a, b), std::max(a, b)});
  return options.latency_s + options.latency_jitter_s * UniformDraw(key);
}

double RadioGate::Arrival(RobotId sender, std::size_t bytes, double stamp) const {
  const double transmission = options_.bandwidth_bytes_per_s > 0.0
                                  ? static_cast<double>(bytes) / options_.bandwidth_bytes_per_s
                                  : 0.0;
  return stamp + LinkLatency(options_, self_, sender) + transmission;
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
