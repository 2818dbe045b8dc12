#include "agent/peer_state.h"

namespace mapmesh {

const char* ToString(PeerStage stage) {
  switch (stage) {
    case PeerStage::kUnaligned: return "unaligned";
    case PeerStage::kCandidate: return "candidate";
    case PeerStage::kAligned: return "aligned";
    case PeerStage::kSuperseded: return "superseded";
    case PeerStage::kDropped: return "dropped";
  }
  return "unknown";
}

PeerReport PeerState::Report(double now, double silent_after_s) const {
  PeerReport r;
  static_cast<PeerCounters&>(r) = counters;
  r.key = key;
  r.stage = stage;
  r.own_checkpoint = own_checkpoint;
  r.origin_stamp = origin_stamp;
  r.local_landmarks = has_local ? static_cast<int>(local.size()) : 0;
  r.global_landmarks = has_global || own_checkpoint ? static_cast<int>(global.size()) : 0;
  r.aligned = Aligned();
  r.ever_aligned = ever_aligned;
  r.dropped = counters.drops > 0 && !Aligned();
  r.stale = stale;
  r.stale_since = stale_since;
  r.frozen = Frozen();
  r.silent = Silent(now, silent_after_s);
  r.last_heard = last_heard;
  r.aligned_since = aligned_since;
  r.to_own = to_own;
  r.to_own_cov = to_own_cov;
  r.relayed = relayed;
  r.superseded = stage == PeerStage::kSuperseded;
  r.refuted_by = refuted_by;
  r.centroid = centroid;
  r.failures = failures;
  r.last_verdict = last_verdict;
  r.aligned_by = aligned_by;
  r.first_aligned_by = first_aligned_by;
  return r;
}

}  // namespace mapmesh
