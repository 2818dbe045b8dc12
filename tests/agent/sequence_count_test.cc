#include "agent/sequence_count.h"

#include <gtest/gtest.h>

#include <random>

namespace mapmesh {
namespace {

double At(std::uint32_t seq) { return 0.05 * seq; }  // a 20 Hz stream

TEST(SequenceCount, GapsAreLostAndTheFirstNumberIsWhereTheStreamWasJoined) {
  SequenceCount c;
  for (std::uint32_t s : {500u, 501u, 504u, 505u, 509u})
    EXPECT_EQ(c.Offer(s, At(s)), SequenceCount::Verdict::kInSequence);
  EXPECT_EQ(c.first(), 500u);
  EXPECT_EQ(c.received(), 5u);
  EXPECT_EQ(c.lost(), 5u);  // 502, 503, 506, 507, 508 (the last gap still provisional)
  EXPECT_EQ(c.out_of_sequence(), 0u);
}

// The glitched scan of issue R2: one number far ahead, then the stream goes on.
TEST(SequenceCount, ALoneNumberFarAheadIsOutOfSequenceAndCostsNoLoss) {
  SequenceCount c;
  for (std::uint32_t s = 0; s < 10; ++s) c.Offer(s, At(s));
  EXPECT_EQ(c.Offer(999999, At(10)), SequenceCount::Verdict::kInSequence);  // no rate known yet: cannot tell
  EXPECT_EQ(c.lost(), 999989u);                                             // provisionally
  EXPECT_EQ(c.Offer(10, At(10)), SequenceCount::Verdict::kInSequence);
  EXPECT_EQ(c.lost(), 0u);
  EXPECT_EQ(c.out_of_sequence(), 1u);
  // Real losses after it are counted again.
  c.Offer(13, At(13));
  c.Offer(14, At(14));
  EXPECT_EQ(c.received(), 13u);
  EXPECT_EQ(c.lost(), 2u);
}

// Once the stream's rate is known, a number further ahead than its stamp allows is out of
// sequence at once, even as the last message of all.
TEST(SequenceCount, AGapTheStreamsRateCannotExplainIsOutOfSequenceAtOnce) {
  SequenceCount c;
  for (std::uint32_t s = 0; s < 40; ++s) c.Offer(s, At(s));  // 1.95 s at 20 Hz
  EXPECT_EQ(c.Offer(999999, At(40)), SequenceCount::Verdict::kOutOfSequence);
  EXPECT_EQ(c.lost(), 0u);
  EXPECT_EQ(c.received(), 40u);
  // A real stall: 3 s without a message (60 lost), within the rate's bound.
  EXPECT_EQ(c.Offer(100, At(100)), SequenceCount::Verdict::kInSequence);
  EXPECT_EQ(c.lost(), 60u);
  EXPECT_EQ(c.received(), 41u);
}

// Before anything else: the forged number first, then the stream (from its start, or joined
// later by a restarted process).
TEST(SequenceCount, AForgedFirstNumberIsOutOfSequenceOnceTheStreamComes) {
  for (std::uint32_t start : {0u, 500u}) {
    SequenceCount c;
    c.Offer(999999, At(start));
    for (std::uint32_t s = start; s < start + 10; ++s)
      EXPECT_EQ(c.Offer(s, At(s)), SequenceCount::Verdict::kInSequence);
    EXPECT_EQ(c.first(), start);
    EXPECT_EQ(c.received(), 10u);
    EXPECT_EQ(c.lost(), 0u);
    EXPECT_EQ(c.out_of_sequence(), 1u);
  }
}

TEST(SequenceCount, NumbersBehindTheStreamAreOutOfSequence) {
  SequenceCount c;
  c.Offer(5, At(5));
  c.Offer(6, At(6));
  EXPECT_EQ(c.Offer(3, At(3)), SequenceCount::Verdict::kOutOfSequence);
  EXPECT_EQ(c.Offer(6, At(6)), SequenceCount::Verdict::kOutOfSequence);
  c.Offer(9, At(9));                                                  // a gap, provisional ...
  EXPECT_EQ(c.Offer(7, At(7)), SequenceCount::Verdict::kInSequence);  // ... and 9 was ahead of the stream
  EXPECT_EQ(c.Offer(9, At(9)), SequenceCount::Verdict::kInSequence);  // a gap again (8), provisional
  EXPECT_EQ(c.Offer(9, At(9)), SequenceCount::Verdict::kOutOfSequence);
  EXPECT_EQ(c.received(), 4u);  // 5, 6, 7, 9
  EXPECT_EQ(c.lost(), 1u);      // 8
  EXPECT_EQ(c.out_of_sequence(), 4u);
}

// Seeded random streams: genuine messages with random losses, forged numbers far ahead slipped
// in (first too, never two in a row; last too, once the stream's rate is known). The counts are exact, whatever the pattern.
TEST(SequenceCount, CountsAreExactOnRandomStreamsWithLossesAndForgedNumbers) {
  for (std::uint64_t seed = 1; seed <= 200; ++seed) {
    std::mt19937_64 rng(seed);
    std::bernoulli_distribution lose(0.2), forge(0.05);
    std::uniform_int_distribution<std::uint32_t> ahead(1000, 2000000);
    const std::uint32_t first = std::uniform_int_distribution<std::uint32_t>(0, 1000)(rng);
    const std::uint32_t n = 300;
    SequenceCount c;
    std::uint32_t delivered = 0, lost = 0, forged = 0, last = first;
    bool any = false, forged_last = false;
    if (forge(rng)) {  // before the stream's first message
      c.Offer(first + ahead(rng), At(first));
      ++forged;
      forged_last = true;
    }
    for (std::uint32_t s = first; s < first + n; ++s) {
      if (any && s + 1 < first + n && lose(rng)) continue;  // the first and the last always arrive
      if (any && !forged_last && forge(rng)) {
        c.Offer(s + ahead(rng), At(s));
        ++forged;
        forged_last = true;
        --s;  // the genuine one still comes
        continue;
      }
      forged_last = false;
      if (any) lost += s - last - 1;
      c.Offer(s, At(s));
      ++delivered;
      last = s;
      any = true;
    }
    c.Offer(last + ahead(rng), At(last));  // the very last: the rate tells
    ++forged;
    SCOPED_TRACE(seed);
    EXPECT_EQ(c.first(), first);
    EXPECT_EQ(c.received(), delivered);
    EXPECT_EQ(c.lost(), lost);
    EXPECT_EQ(c.out_of_sequence(), forged);
    EXPECT_EQ(c.received() + c.lost(), n);
  }
}

}  // namespace
}  // namespace mapmesh
