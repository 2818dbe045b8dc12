#include "agent/sequence_count.h"

#include <algorithm>

namespace mapmesh {

bool SequenceCount::Plausible(std::uint32_t seq, double stamp) const {
  const double span = last_stamp_ - first_stamp_;
  if (!(span >= 1.0) || last_ == *first_) return true;  // no rate known yet
  const double rate = static_cast<double>(last_ - *first_) / span;
  const double gap = static_cast<double>(seq - last_ - 1);
  return gap <= kGapSlack + kGapRateFactor * rate * std::max(0.0, stamp - last_stamp_);
}

SequenceCount::Verdict SequenceCount::Offer(std::uint32_t seq, double stamp) {
  if (!first_) {
    first_ = seq;
    first_stamp_ = last_stamp_ = stamp;
    last_ = seq;
    ++received_;
    return Verdict::kInSequence;
  }
  if (received_ == 1 && !pending_ && seq < last_) {
    // The stream's first number is followed by a smaller one: that first was not of it.
    ++out_of_sequence_;
    first_ = seq;
    first_stamp_ = last_stamp_ = stamp;
    last_ = seq;
    return Verdict::kInSequence;
  }
  if (pending_) {
    const std::uint32_t ahead = *pending_;
    if (seq > ahead) {
      // The stream goes on beyond the gap: it was a loss.
      lost_ += ahead - last_ - 1;
      ++received_;
      last_ = ahead;
      last_stamp_ = pending_stamp_;
      pending_.reset();
    } else if (seq > last_ && seq < ahead) {
      // The stream goes on behind the number ahead: that one was not of it.
      ++out_of_sequence_;
      pending_.reset();
    } else {
      ++out_of_sequence_;
      return Verdict::kOutOfSequence;
    }
  }
  if (seq <= last_ || !Plausible(seq, stamp)) {
    ++out_of_sequence_;
    return Verdict::kOutOfSequence;
  }
  if (seq == last_ + 1) {
    last_ = seq;
    last_stamp_ = stamp;
    ++received_;
  } else {
    pending_ = seq;
    pending_stamp_ = stamp;
  }
  return Verdict::kInSequence;
}

}  // namespace mapmesh
