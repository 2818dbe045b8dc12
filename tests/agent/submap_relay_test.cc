#include "agent/submap_relay.h"

#include "common/map/submap_digest.h"

#include <gtest/gtest.h>

#include <random>

namespace mapmesh {
namespace {

WireSubmap Submap(RobotId robot, std::uint32_t incarnation, std::uint32_t index, int landmarks = 2, double x = 1.0) {
  WireSubmap s;
  s.id = {robot, incarnation, index};
  s.opened_s = 10.0 * index;
  s.closed_s = 10.0 * index + 9.0;
  for (int i = 0; i < landmarks; ++i) s.keys.push_back(static_cast<std::uint32_t>(i));
  s.x = Eigen::VectorXd::Constant(3 + 2 * landmarks, x);
  EXPECT_TRUE(s.SetCovariance(Eigen::MatrixXd::Identity(3 + 2 * landmarks, 3 + 2 * landmarks) * 0.01));
  return s;
}

SubmapRelayOptions Options() {
  SubmapRelayOptions o;
  o.send_bytes = 100000;
  o.resend_after_s = 6.0;
  o.advert_max_age_s = 6.0;
  return o;
}

void AddOwn(SubmapRelay& r, const WireSubmap& s) {
  const std::vector<std::uint8_t> b = EncodeSubmap(s);
  ASSERT_FALSE(b.empty());
  EXPECT_EQ(r.AddOwn(s, b), SubmapRelay::Offer::kNew);
}

// The submaps sent, decoded.
std::vector<WireSubmap> Decoded(const std::vector<const SubmapBlob*>& sent) {
  std::vector<WireSubmap> out;
  for (const SubmapBlob* b : sent) {
    const SubmapDecodeResult d = DecodeSubmap(b->bytes);
    EXPECT_TRUE(d.ok());
    out.push_back(d.submap);
  }
  return out;
}

std::vector<SubmapId> Ids(const std::vector<const SubmapBlob*>& sent) {
  std::vector<SubmapId> out;
  for (const WireSubmap& s : Decoded(sent)) out.push_back(s.id);
  return out;
}

// A restarted agent's submaps from its checkpoint are held again, beyond max_held, counted as
// restored, and go to a peer that lacks them as own ones do (none was heard from a peer).
TEST(SubmapRelay, RestoredSubmapsAreHeldAndGoToAPeerThatLacksThem) {
  SubmapRelayOptions o = Options();
  o.max_held = 1;
  SubmapRelay r(o);
  const std::vector<WireSubmap> kept = {Submap(1, 1, 0), Submap(1, 1, 1), Submap(4, 2, 0)};
  for (const WireSubmap& s : kept) EXPECT_EQ(r.Restore(s, EncodeSubmap(s)), SubmapRelay::Offer::kNew);
  EXPECT_EQ(r.Restore(kept[0], EncodeSubmap(kept[0])), SubmapRelay::Offer::kDuplicate);
  const WireSubmap other = Submap(1, 1, 1, 2, 5.0);
  EXPECT_EQ(r.Restore(other, EncodeSubmap(other)), SubmapRelay::Offer::kConflict);
  EXPECT_EQ(r.book().size(), 3u);
  EXPECT_EQ(r.counters().restored, 3u);
  EXPECT_EQ(r.counters().received_new, 0u);
  EXPECT_EQ(r.counters().conflicts, 1u);
  const std::vector<SubmapChain> has_robot_4 = {{4, 2, 1}};
  r.OnAdvert({2, 1}, has_robot_4, 10.0);
  EXPECT_EQ(Ids(r.Due({2}, 10.5)), (std::vector<SubmapId>{{1, 1, 0}, {1, 1, 1}}));
}

// Nothing goes out until a peer in range says what it lacks: a peer out of range, or whose
// advertisement is older than advert_max_age_s, is not listening.
TEST(SubmapRelay, SendsOnlyWhatAPeerInRangeLacks) {
  SubmapRelay r(Options());
  for (std::uint32_t i = 0; i < 3; ++i) AddOwn(r, Submap(1, 1, i));
  EXPECT_TRUE(r.Due({2}, 10.0).empty());  // no advertisement yet
  const std::vector<SubmapChain> has_first = {{1, 1, 1}, {2, 1, 4}};
  r.OnAdvert({2, 1}, has_first, 10.0);
  EXPECT_TRUE(r.Due({3}, 10.0).empty());  // robot 2 out of range
  EXPECT_TRUE(r.Due({2}, 16.5).empty());  // its advertisement too old
  EXPECT_EQ(Ids(r.Due({2}, 12.0)), (std::vector<SubmapId>{{1, 1, 1}, {1, 1, 2}}));
  // Once its advertisement shows them, they do not go again, however long after.
  const std::vector<SubmapChain> has_all = {{1, 1, 3}};
  r.OnAdvert({2, 1}, has_all, 14.0);
  EXPECT_TRUE(r.Due({2}, 20.0).empty());
  EXPECT_EQ(r.counters().sent, 2u);
  EXPECT_EQ(r.counters().sent_again, 0u);
}

// Issue R3: a robot's owner advertises the digests of its own chain's latest closed submaps. A
// relay's forged copy of an index the owner advertised is dropped when the owner is heard
// (owner_conflicts), so is one of an index the owner has not closed (ahead_of_owner); the
// advertisement then lacks them, and the owner's genuine ones are taken. A forged copy offered
// later, against a digest the owner advertised, is refused.
TEST(SubmapRelay, TheOwnersDigestsDisownForgedCopies) {
  SubmapRelay owner(Options()), holder(Options());
  const std::vector<WireSubmap> genuine = {Submap(2, 1, 0, 2, 1.0), Submap(2, 1, 1, 2, 1.0)};
  for (const WireSubmap& s : genuine) AddOwn(owner, s);
  const std::vector<std::uint64_t> digests = owner.OwnDigests({2, 1});
  ASSERT_EQ(digests.size(), 2u);
  EXPECT_EQ(digests[1], SubmapDigest(EncodeSubmap(genuine[1])));
  EXPECT_TRUE(owner.OwnDigests({3, 1}).empty());
  // A relay brought index 0 genuine, index 1 forged, and index 2 (which robot 2 never closed).
  const WireSubmap forged1 = Submap(2, 1, 1, 2, 7.0), forged2 = Submap(2, 1, 2, 2, 7.0);
  for (const WireSubmap* s : {&genuine[0], &forged1, &forged2})
    EXPECT_EQ(holder.Add(*s, EncodeSubmap(*s), 5.0), SubmapRelay::Offer::kNew);
  EXPECT_EQ(holder.book().ChainLength(2, 1), 3u);
  // Robot 2's own map: count 2, the digests of both.
  EXPECT_EQ(holder.OnOwnerAdvert({2, 1}, 2, digests), 2u);
  EXPECT_EQ(holder.counters().owner_conflicts, 1u);
  EXPECT_EQ(holder.counters().ahead_of_owner, 1u);
  EXPECT_EQ(holder.book().Ids(), (std::vector<SubmapId>{{2, 1, 0}}));
  EXPECT_EQ(holder.Advert(), (std::vector<SubmapChain>{{2, 1, 1}}));  // what the owner then sends
  EXPECT_EQ(holder.book().bytes(), EncodeSubmap(genuine[0]).size());
  // The forgery again from a relay: refused against the owner's digest; the owner's is taken.
  EXPECT_EQ(holder.Add(forged1, EncodeSubmap(forged1), 6.0), SubmapRelay::Offer::kConflict);
  EXPECT_EQ(holder.counters().owner_conflicts, 2u);
  EXPECT_EQ(holder.Add(genuine[1], EncodeSubmap(genuine[1]), 6.0), SubmapRelay::Offer::kNew);
  // The owner's word again changes nothing; more digests than its count say nothing.
  EXPECT_EQ(holder.OnOwnerAdvert({2, 1}, 2, digests), 0u);
  EXPECT_EQ(holder.OnOwnerAdvert({2, 1}, 1, digests), 0u);
  EXPECT_EQ(holder.book().ChainLength(2, 1), 2u);
  // Digests of the latest only (kOwnDigests); an owner's chain longer than that advertises those.
  SubmapRelay long_owner(Options());
  for (std::uint32_t i = 0; i < SubmapRelay::kOwnDigests + 3; ++i) AddOwn(long_owner, Submap(5, 1, i));
  const std::vector<std::uint64_t> latest = long_owner.OwnDigests({5, 1});
  ASSERT_EQ(latest.size(), SubmapRelay::kOwnDigests);
  EXPECT_EQ(latest.back(), SubmapDigest(EncodeSubmap(Submap(5, 1, SubmapRelay::kOwnDigests + 2))));
}

// A submap sent and still lacked (lost on the way) goes again after resend_after_s, not before.
TEST(SubmapRelay, ALostSubmapIsSentAgainAfterTheResendDelay) {
  SubmapRelay r(Options());
  AddOwn(r, Submap(1, 1, 0));
  const std::vector<SubmapChain> none;
  r.OnAdvert({2, 1}, none, 10.0);
  EXPECT_EQ(r.Due({2}, 10.0).size(), 1u);
  r.OnAdvert({2, 1}, none, 12.0);
  EXPECT_TRUE(r.Due({2}, 12.0).empty());
  EXPECT_TRUE(r.Due({2}, 15.99).empty());
  r.OnAdvert({2, 1}, none, 16.0);
  EXPECT_EQ(r.Due({2}, 16.0).size(), 1u);
  EXPECT_EQ(r.counters().sent, 2u);
  EXPECT_EQ(r.counters().sent_again, 1u);
}

// A submap just heard (another robot broadcast it) is not sent on a peer's advertisement from
// before: the peer probably heard it too. Its next advertisement decides.
TEST(SubmapRelay, ASubmapJustHeardWaitsForThePeersNextAdvertisement) {
  SubmapRelay r(Options());
  const std::vector<SubmapChain> none;
  r.OnAdvert({2, 1}, none, 10.0);
  const WireSubmap s = Submap(3, 1, 0);
  ASSERT_EQ(r.Add(s, EncodeSubmap(s), 10.0), SubmapRelay::Offer::kNew);
  EXPECT_TRUE(r.Due({2}, 10.0).empty());  // robot 2 spoke before it went round
  const std::vector<SubmapChain> got = {{3, 1, 1}};
  r.OnAdvert({2, 1}, got, 12.0);
  EXPECT_TRUE(r.Due({2}, 12.0).empty());  // it heard it
  r.OnAdvert({4, 1}, none, 12.0);
  EXPECT_EQ(Ids(r.Due({2, 4}, 12.0)), (std::vector<SubmapId>{{3, 1, 0}}));  // robot 4 did not
  // Heard again (a duplicate) later: robot 4 is waited for again.
  EXPECT_EQ(r.Add(s, EncodeSubmap(s), 20.0), SubmapRelay::Offer::kDuplicate);
  r.OnAdvert({4, 1}, none, 20.0);
  EXPECT_TRUE(r.Due({4}, 20.0).empty());
  r.OnAdvert({4, 1}, none, 22.0);
  EXPECT_EQ(r.Due({4}, 22.0).size(), 1u);
}

// Within send_bytes, lowest indices first across chains (every chain grows alike); the first one
// due goes whatever its size, and the rest wait for later publications.
TEST(SubmapRelay, TheBudgetTakesTheLowestIndicesFirst) {
  SubmapRelayOptions o = Options();
  const std::size_t one = SubmapPayloadBytes(2);
  o.send_bytes = 3 * one;
  SubmapRelay r(o);
  for (std::uint32_t i = 0; i < 3; ++i) {
    AddOwn(r, Submap(1, 1, i));
    ASSERT_EQ(r.Add(Submap(5, 2, i), EncodeSubmap(Submap(5, 2, i)), -1.0), SubmapRelay::Offer::kNew);
  }
  const std::vector<SubmapChain> none;
  r.OnAdvert({2, 1}, none, 0.0);
  EXPECT_EQ(Ids(r.Due({2}, 0.0)), (std::vector<SubmapId>{{1, 1, 0}, {5, 2, 0}, {1, 1, 1}}));
  EXPECT_EQ(r.counters().held_back, 3u);
  EXPECT_EQ(Ids(r.Due({2}, 0.0)), (std::vector<SubmapId>{{5, 2, 1}, {1, 1, 2}, {5, 2, 2}}));
  o.send_bytes = 1;
  SubmapRelay tight(o);
  AddOwn(tight, Submap(1, 1, 0, 30));
  AddOwn(tight, Submap(1, 1, 1));
  tight.OnAdvert({2, 1}, none, 0.0);
  EXPECT_EQ(Ids(tight.Due({2}, 0.0)), (std::vector<SubmapId>{{1, 1, 0}}));
}

// Issue R3: the budget is the link's. A submap larger than send_bytes goes alone when a
// publication's budget is whole, and the next publications pay what it took beyond before they
// send anything (open submaps relayed included); over any run of publications no more than
// send_bytes each go, plus one submap.
TEST(SubmapRelay, ASubmapBeyondTheBudgetIsPaidForByTheNextPublications) {
  SubmapRelayOptions o = Options();
  const std::size_t small = SubmapPayloadBytes(2), big = SubmapPayloadBytes(30);
  o.send_bytes = 2 * small;
  SubmapRelay r(o);
  AddOwn(r, Submap(1, 1, 0, 30));
  AddOwn(r, Submap(1, 1, 1));
  AddOwn(r, Submap(1, 1, 2));
  r.OnAdvert({2, 1}, std::vector<SubmapChain>{}, 0.0);
  EXPECT_EQ(Ids(r.Due({2}, 0.0)), (std::vector<SubmapId>{{1, 1, 0}}));
  const std::size_t owed = big - o.send_bytes, publications = (owed + o.send_bytes - 1) / o.send_bytes;
  std::size_t sent = big;
  int k = 1;
  for (; k <= static_cast<int>(publications); ++k) {
    const double now = 0.1 * k;
    EXPECT_TRUE(r.Due({2}, now).empty()) << k;
    EXPECT_TRUE(r.DueOpen({2}, now).empty()) << k;
  }
  EXPECT_EQ(r.counters().debt_paid, owed);
  // Paid: the remainder of the last paying publication's budget went unused; now both go.
  const std::vector<const SubmapBlob*> next = r.Due({2}, 0.1 * k);
  EXPECT_EQ(Ids(next), (std::vector<SubmapId>{{1, 1, 1}, {1, 1, 2}}));
  for (const SubmapBlob* b : next) sent += b->bytes.size();
  EXPECT_LE(sent, static_cast<std::size_t>(k + 1) * o.send_bytes + big);
  EXPECT_GT(r.counters().held_back, 0u);
  // Within the budget nothing is owed: a publication sends what fits and the next starts whole.
  SubmapRelay plain(Options());
  AddOwn(plain, Submap(1, 1, 0, 30));
  plain.OnAdvert({2, 1}, std::vector<SubmapChain>{}, 0.0);
  EXPECT_EQ(plain.Due({2}, 0.0).size(), 1u);
  EXPECT_EQ(plain.counters().debt_paid, 0u);
}

// Issue R3: the book is bounded in bytes, a chain at max_chain_bytes and the peers' submaps
// at max_bytes_held in all (the agent's own and a checkpoint's restored always enter).
TEST(SubmapRelay, TheBookIsBoundedInBytesPerChainAndInAll) {
  SubmapRelayOptions o = Options();
  const std::size_t one = SubmapPayloadBytes(2);
  o.max_chain_bytes = 2 * one;
  o.max_bytes_held = 3 * one;
  SubmapRelay r(o);
  for (std::uint32_t i = 0; i < 3; ++i) AddOwn(r, Submap(1, 1, i));  // own: not counted against either
  const auto add = [&](RobotId robot, std::uint32_t index) {
    const WireSubmap s = Submap(robot, 1, index);
    return r.Add(s, EncodeSubmap(s), 0.0);
  };
  EXPECT_EQ(add(3, 0), SubmapRelay::Offer::kNew);
  EXPECT_EQ(add(3, 1), SubmapRelay::Offer::kNew);
  EXPECT_EQ(add(3, 2), SubmapRelay::Offer::kFull);  // its chain is full
  EXPECT_EQ(r.counters().chain_full, 1u);
  EXPECT_EQ(add(4, 0), SubmapRelay::Offer::kNew);
  EXPECT_EQ(add(5, 0), SubmapRelay::Offer::kFull);  // all of them are
  EXPECT_EQ(r.counters().full, 1u);
  EXPECT_EQ(add(3, 0), SubmapRelay::Offer::kDuplicate);  // held ones still recognised
  const WireSubmap restored = Submap(5, 1, 0);
  EXPECT_EQ(r.Restore(restored, EncodeSubmap(restored)), SubmapRelay::Offer::kNew);
  EXPECT_EQ(r.book().ChainBytes(3, 1), 2 * one);
  EXPECT_EQ(r.book().bytes(), 7 * one);
}

// Each identity enters once; a different submap under a held identity is refused and counted;
// beyond max_held a peer's new submap is refused, the agent's own never.
TEST(SubmapRelay, EachIdentityOnceAndTheBookIsBounded) {
  SubmapRelayOptions o = Options();
  o.max_held = 2;
  SubmapRelay r(o);
  const WireSubmap a = Submap(3, 1, 0);
  EXPECT_EQ(r.Add(a, EncodeSubmap(a), 0.0), SubmapRelay::Offer::kNew);
  EXPECT_EQ(r.Add(a, EncodeSubmap(a), 0.0), SubmapRelay::Offer::kDuplicate);
  const WireSubmap forged = Submap(3, 1, 0, 2, 7.0);
  EXPECT_EQ(r.Add(forged, EncodeSubmap(forged), 0.0), SubmapRelay::Offer::kConflict);
  const WireSubmap b = Submap(3, 1, 1);
  EXPECT_EQ(r.Add(b, EncodeSubmap(b), 0.0), SubmapRelay::Offer::kNew);
  const WireSubmap c = Submap(3, 1, 2);
  EXPECT_EQ(r.Add(c, EncodeSubmap(c), 0.0), SubmapRelay::Offer::kFull);
  EXPECT_EQ(r.Add(a, EncodeSubmap(a), 0.0), SubmapRelay::Offer::kDuplicate);  // held ones are still recognised
  AddOwn(r, Submap(1, 1, 0));
  EXPECT_EQ(r.book().size(), 3u);
  EXPECT_EQ(r.counters().received_new, 2u);
  EXPECT_EQ(r.counters().duplicates, 2u);
  EXPECT_EQ(r.counters().conflicts, 1u);
  EXPECT_EQ(r.counters().full, 1u);
  EXPECT_EQ(r.counters().own, 1u);
  EXPECT_EQ(r.Advert(), (std::vector<SubmapChain>{{1, 1, 1}, {3, 1, 2}}));
}

// The protocol over a line of robots that hear only their neighbours, through a seeded lossy
// radio, in lockstep ticks (what is sent at one tick arrives at the next): every robot ends up
// holding every robot's whole chain, however many hops away, each submap entered once; and a
// submap is sent a bounded number of times (once per neighbourhood, plus resends for losses).
TEST(SubmapRelay, EveryChainReachesEveryHopThroughALossyLine) {
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const int n = 6;
    const std::uint32_t per_robot = 8;
    const double period = 2.0, loss = 0.3;
    std::mt19937_64 rng(seed);
    std::bernoulli_distribution lost(loss);
    SubmapRelayOptions o = Options();
    o.resend_after_s = 3 * period;
    o.advert_max_age_s = 3 * period;
    o.send_bytes = 4 * SubmapPayloadBytes(2);
    std::vector<SubmapRelay> relays(n, SubmapRelay(o));
    struct Message {
      int from;
      std::vector<SubmapChain> advert;
      std::vector<std::vector<std::uint8_t>> submaps;
    };
    std::vector<Message> in_flight;
    const int ticks = 120;
    for (int t = 0; t < ticks; ++t) {
      const double now = t * period;
      // Delivery of the last tick's messages to the sender's neighbours, each copy lost alone.
      for (const Message& m : in_flight) {
        for (int to : {m.from - 1, m.from + 1}) {
          if (to < 0 || to >= n || lost(rng)) continue;
          relays[to].OnAdvert({static_cast<RobotId>(m.from + 1), 1}, m.advert, now);
          for (const auto& b : m.submaps) {
            const SubmapDecodeResult d = DecodeSubmap(b);
            ASSERT_TRUE(d.ok());
            relays[to].Add(d.submap, b, now);
          }
        }
      }
      in_flight.clear();
      for (int i = 0; i < n; ++i) {
        const auto robot = static_cast<RobotId>(i + 1);
        if (t % 5 == 0 && t / 5 < static_cast<int>(per_robot)) {
          const WireSubmap own = Submap(robot, 1, static_cast<std::uint32_t>(t / 5), 2, robot);
          relays[i].AddOwn(own, EncodeSubmap(own));
        }
        std::set<RobotId> in_range;
        if (i > 0) in_range.insert(robot - 1);
        if (i + 1 < n) in_range.insert(robot + 1);
        Message m{i, relays[i].Advert(), {}};
        for (const auto* b : relays[i].Due(in_range, now)) m.submaps.push_back(b->bytes);
        in_flight.push_back(std::move(m));
      }
    }
    std::uint32_t sent = 0;
    for (int i = 0; i < n; ++i) {
      const SubmapRelay& r = relays[i];
      EXPECT_EQ(r.book().size(), n * per_robot) << "seed " << seed << " robot " << i + 1;
      for (int j = 0; j < n; ++j) {
        EXPECT_EQ(r.book().ChainLength(static_cast<RobotId>(j + 1), 1), per_robot) << "seed " << seed;
      }
      EXPECT_EQ(r.counters().conflicts, 0u);
      EXPECT_EQ(r.counters().received_new + r.counters().own, n * per_robot);
      sent += r.counters().sent;
    }
    // Each submap is sent by about every robot once (each must pass it to the next hop); the
    // losses add resends. Flooding every submap at every tick would send 120 times as many.
    EXPECT_LE(sent, 3u * n * n * per_robot) << "seed " << seed;
    EXPECT_GE(sent, static_cast<std::uint32_t>(n - 1) * per_robot) << "seed " << seed;
  }
}

// Robot 3's open submap, as this relay took it at `at` (its index continues two closed ones).
WireSubmap Open(double closed_s, std::uint32_t index = 2, RobotId robot = 3) {
  WireSubmap s = Submap(robot, 1, index);
  s.closed_s = closed_s;
  return s;
}

SubmapRelay::Offer AddOpen(SubmapRelay& r, const WireSubmap& s, double now) {
  return r.AddOpen(s, EncodeSubmap(s), now);
}

std::vector<double> Ends(const std::vector<const SubmapBlob*>& sent) {
  std::vector<double> out;
  for (const WireSubmap& s : Decoded(sent)) out.push_back(s.closed_s);
  return out;
}

// A robot's open submap goes on only once the robot fell silent (unchanged for
// open_silent_after_s), to a peer in range that holds the chain up to it but not it, and again
// only after resend_after_s while the peer still lacks it; the latest version is kept; the
// closed submap of its index replaces it.
TEST(SubmapRelay, AnOpenSubmapGoesOnOnceItsRobotFellSilentToAPeerThatLacksIt) {
  SubmapRelayOptions o = Options();
  o.open_silent_after_s = 6.0;
  SubmapRelay r(o);
  for (std::uint32_t i = 0; i < 2; ++i) {
    const WireSubmap s = Submap(3, 1, i);
    EXPECT_EQ(r.Add(s, EncodeSubmap(s), 0.0), SubmapRelay::Offer::kNew);
  }
  EXPECT_EQ(AddOpen(r, Open(29.0), 10.0), SubmapRelay::Offer::kNew);
  EXPECT_EQ(r.Advert(), (std::vector<SubmapChain>{{3, 1, 2, 29.0}}));
  const std::vector<SubmapChain> lacks = {{3, 1, 2, 0.0}};
  r.OnAdvert({1, 1}, lacks, 12.0);
  EXPECT_TRUE(r.DueOpen({1}, 12.0).empty());  // robot 3 is still heard
  EXPECT_EQ(AddOpen(r, Open(31.0), 12.0), SubmapRelay::Offer::kNew);
  EXPECT_EQ(AddOpen(r, Open(30.0), 13.0), SubmapRelay::Offer::kDuplicate);     // an older one, late
  EXPECT_EQ(AddOpen(r, Open(31.0, 1), 13.0), SubmapRelay::Offer::kDuplicate);  // an earlier index
  EXPECT_EQ(r.open().at({3, 1}).closed_s, 31.0);
  EXPECT_EQ(r.counters().open_taken, 2u);
  EXPECT_TRUE(r.DueOpen({1}, 17.0).empty());  // unchanged for 5 s only
  EXPECT_TRUE(r.Due({1}, 18.0).empty());      // the closed ones it has
  EXPECT_EQ(Ends(r.DueOpen({1}, 18.0)), (std::vector<double>{31.0}));
  r.OnAdvert({1, 1}, lacks, 18.5);            // spoken before it arrived
  EXPECT_TRUE(r.DueOpen({1}, 19.0).empty());  // sent: not again before resend_after_s
  const std::vector<SubmapChain> has_it = {{3, 1, 2, 31.0}};
  r.OnAdvert({1, 1}, has_it, 20.0);
  EXPECT_TRUE(r.DueOpen({1}, 25.0).empty());
  r.OnAdvert({1, 1}, lacks, 26.0);  // it lost it (restarted)
  EXPECT_EQ(Ends(r.DueOpen({1}, 26.0)), (std::vector<double>{31.0}));
  // Robot 2 lacks it too, but is out of range until it is.
  r.OnAdvert({2, 1}, lacks, 33.0);
  EXPECT_TRUE(r.DueOpen({}, 33.0).empty());
  EXPECT_EQ(Ends(r.DueOpen({2}, 33.0)), (std::vector<double>{31.0}));
  EXPECT_EQ(r.counters().open_relayed, 3u);
  EXPECT_EQ(r.counters().open_bytes_relayed, 3 * EncodeSubmap(Open(31.0)).size());
  // Not to its own robot, nor to a peer that cannot chain it, holds its closed one, or holds a
  // later open one (beyond a closed one it lacks).
  const std::vector<SubmapChain> own = {{3, 1, 2, 0.0}}, short_chain = {{3, 1, 1, 0.0}}, closed = {{3, 1, 3, 0.0}},
                                 later = {{3, 1, 2, 45.0}};
  r.OnAdvert({3, 1}, own, 40.0);
  r.OnAdvert({4, 1}, short_chain, 40.0);
  r.OnAdvert({5, 1}, closed, 40.0);
  r.OnAdvert({6, 1}, later, 40.0);
  EXPECT_TRUE(r.DueOpen({3, 4, 5, 6}, 40.0).empty());
  r.OnAdvert({6, 1}, lacks, 40.0);
  EXPECT_EQ(Ends(r.DueOpen({3, 4, 5, 6}, 40.0)), (std::vector<double>{31.0}));  // the one that lacks it
  // Its closed submap arrives: the open one is gone, no open one of its index enters again, and
  // the chain advertised is the closed one.
  const WireSubmap two = Submap(3, 1, 2);
  EXPECT_EQ(r.Add(two, EncodeSubmap(two), 41.0), SubmapRelay::Offer::kNew);
  EXPECT_TRUE(r.open().empty());
  EXPECT_EQ(AddOpen(r, Open(45.0), 42.0), SubmapRelay::Offer::kDuplicate);
  EXPECT_TRUE(r.open().empty());
  EXPECT_EQ(r.Advert(), (std::vector<SubmapChain>{{3, 1, 3, 0.0}}));
}

// A chain of which only an open submap is held is advertised with count 0; an open submap held
// beyond the closed ones gives its chain's open_until. A relayed open submap enters only where
// it continues the chain held; max_open bounds the open ones kept; the closed ones and the
// relayed open ones of one publication share send_bytes.
TEST(SubmapRelay, OpenSubmapsAdvertisedBoundedAndWithinTheBudget) {
  SubmapRelayOptions o = Options();
  o.max_open = 2;
  o.open_silent_after_s = 1.0;
  SubmapRelay r(o);
  AddOwn(r, Submap(1, 1, 0));
  EXPECT_EQ(AddOpen(r, Open(5.0, 0, 2), 1.0), SubmapRelay::Offer::kNew);
  EXPECT_EQ(AddOpen(r, Open(25.0, 2, 4), 1.0),
            SubmapRelay::Offer::kNew);  // its publisher's: robot 4's 0 and 1 not held
  EXPECT_EQ(AddOpen(r, Open(5.0, 0, 5), 1.0), SubmapRelay::Offer::kFull);
  EXPECT_EQ(AddOpen(r, Open(6.0, 0, 2), 2.0), SubmapRelay::Offer::kNew);  // a later version still enters
  EXPECT_EQ(r.counters().full, 1u);
  EXPECT_EQ(r.Advert(), (std::vector<SubmapChain>{{1, 1, 1, 0.0}, {2, 1, 0, 6.0}, {4, 1, 0, 25.0}}));
  EXPECT_EQ(r.AddOpen(Open(7.0, 1, 2), EncodeSubmap(Open(7.0, 1, 2)), 3.0, true), SubmapRelay::Offer::kGap);
  EXPECT_EQ(r.AddOpen(Open(8.0, 0, 2), EncodeSubmap(Open(8.0, 0, 2)), 3.0, true), SubmapRelay::Offer::kNew);
  EXPECT_EQ(r.counters().open_gaps, 1u);
  // Robot 6 lacks robot 1's closed submap and robot 2's open one: the closed one spent the
  // budget, so the open one waits (the first of a publication goes whatever its size).
  const std::vector<SubmapChain> lacks = {{2, 1, 0, 0.0}};
  r.OnAdvert({6, 1}, lacks, 10.0);
  const auto closed = r.Due({6}, 10.0);
  ASSERT_EQ(closed.size(), 1u);
  EXPECT_TRUE(r.DueOpen({6}, 10.0, o.send_bytes).empty());
  EXPECT_EQ(r.counters().held_back, 1u);
  EXPECT_EQ(Ends(r.DueOpen({6}, 11.0, closed[0]->bytes.size())), (std::vector<double>{8.0}));
}

// A silent robot's open submap reaches every hop of a line, one relay after another, each
// relay sending it once: every agent holds it, and nobody holds an older one.
TEST(SubmapRelay, ASilentRobotsOpenSubmapReachesEveryHopOnce) {
  const int n = 5;
  const double period = 2.0;
  SubmapRelayOptions o = Options();
  o.open_silent_after_s = 3 * period;
  std::vector<SubmapRelay> relays(n, SubmapRelay(o));
  // Agent 1 (index 0) heard robot 9's chain of two and its open submap, then lost it.
  for (std::uint32_t i = 0; i < 2; ++i) {
    const WireSubmap s = Submap(9, 1, i);
    relays[0].Add(s, EncodeSubmap(s), 0.0);
  }
  AddOpen(relays[0], Open(29.0, 2, 9), 0.0);
  AddOpen(relays[0], Open(30.0, 2, 9), 2.0);
  struct Message {
    int from;
    std::vector<SubmapChain> advert;
    std::vector<std::vector<std::uint8_t>> submaps, open;
  };
  std::vector<Message> in_flight;
  for (int t = 0; t < 60; ++t) {
    const double now = t * period;
    for (const Message& m : in_flight) {
      for (int to : {m.from - 1, m.from + 1}) {
        if (to < 0 || to >= n) continue;
        relays[to].OnAdvert({static_cast<RobotId>(m.from + 1), 1}, m.advert, now);
        for (const auto& b : m.submaps) relays[to].Add(DecodeSubmap(b).submap, b, now);
        for (const auto& b : m.open) relays[to].AddOpen(DecodeSubmap(b).submap, b, now);
      }
    }
    in_flight.clear();
    for (int i = 0; i < n; ++i) {
      std::set<RobotId> in_range;
      if (i > 0) in_range.insert(static_cast<RobotId>(i));
      if (i + 1 < n) in_range.insert(static_cast<RobotId>(i + 2));
      Message m{i, relays[i].Advert(), {}, {}};
      for (const auto* b : relays[i].Due(in_range, now)) m.submaps.push_back(b->bytes);
      for (const auto* b : relays[i].DueOpen(in_range, now)) m.open.push_back(b->bytes);
      in_flight.push_back(std::move(m));
    }
  }
  for (int i = 0; i < n; ++i) {
    const SubmapRelay& r = relays[i];
    EXPECT_EQ(r.book().ChainLength(9, 1), 2u) << "agent " << i + 1;
    ASSERT_EQ(r.open().size(), 1u) << "agent " << i + 1;
    EXPECT_EQ(r.open().at({9, 1}).closed_s, 30.0);
    EXPECT_EQ(r.counters().open_relayed, i + 1 < n ? 1u : 0u) << "agent " << i + 1;
  }
}

}  // namespace
}  // namespace mapmesh
