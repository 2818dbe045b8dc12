#pragma once
// Counts one sensor stream's messages by their sequence numbers: those received in sequence,
// those lost (gaps), and those out of sequence (behind the stream, or a lone number far
// ahead of it). It reads only the sequence numbers it is offered (of messages already
// accepted: plausible, not sent again) and changes nothing else.
//
// One forged number must not corrupt the count. A gap larger than the stream's own rate allows
// over the time its stamp moved (kGapRateFactor times the rate seen so far, plus kGapSlack) is
// no loss: that number is out of sequence at once. A gap within it is provisional until the
// next message: when that one continues the old stream instead, the number ahead was an
// outlier, counted out of sequence, and its gap never was lost. Until then the gap counts as
// lost (a genuine last message after a gap is accounted for), so received() + lost() ==
// last - first + 1 holds for the stream seen so far. The first number is no more trusted: when
// the second is smaller, the first was not of the stream.

#include <cstdint>
#include <optional>

namespace mapmesh {

class SequenceCount {
 public:
  enum class Verdict {
    kInSequence,     // received (a forward gap before it, if any, counted as lost)
    kOutOfSequence,  // behind the stream: not received, not a loss
  };
  // The number and the stamp of an accepted message.
  Verdict Offer(std::uint32_t seq, double stamp);

  static constexpr double kGapRateFactor = 4.0;
  static constexpr std::uint32_t kGapSlack = 16;

  std::uint32_t received() const { return received_ + (pending_ ? 1u : 0u); }
  std::uint32_t lost() const { return lost_ + (pending_ ? *pending_ - last_ - 1 : 0u); }
  std::uint32_t out_of_sequence() const { return out_of_sequence_; }
  // The first sequence number received: the messages sent before it, when the stream was
  // joined late (a restart), were never this process's to receive.
  std::optional<std::uint32_t> first() const { return first_; }

 private:
  // Whether a gap to seq at stamp fits the stream's rate so far.
  bool Plausible(std::uint32_t seq, double stamp) const;

  std::optional<std::uint32_t> first_;
  double first_stamp_ = 0.0;
  std::uint32_t last_ = 0;                // the last one in sequence, confirmed ...
  double last_stamp_ = 0.0;               // ... and its stamp
  std::optional<std::uint32_t> pending_;  // after a forward gap, until the next message tells
  double pending_stamp_ = 0.0;
  std::uint32_t received_ = 0, lost_ = 0, out_of_sequence_ = 0;
};

}  // namespace mapmesh
