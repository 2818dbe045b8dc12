#include "agent/peer_schedule.h"

#include <gtest/gtest.h>

#include <random>

namespace mapmesh {
namespace {

ExchangeOptions Options() {
  ExchangeOptions o;
  o.align_period_s = 5.0;
  o.retry_growth = 0.2;
  o.refine_period_s = 5.0;
  o.max_alignments_per_update = 2;
  o.max_relay_checks_per_update = 4;
  o.max_relay_comparisons_per_update = 64;
  return o;
}

// A peer that sent a first map and was never tried.
PeerFacts Fresh(RobotId robot, std::uint32_t incarnation = 1) {
  PeerFacts f;
  f.key = {robot, incarnation};
  f.has_map = true;
  f.changed = true;
  f.map_size = 20;
  return f;
}

// An aligned live peer, verified at t = 10 with both maps as they are.
PeerFacts Aligned(RobotId robot) {
  PeerFacts f = Fresh(robot);
  f.aligned = true;
  f.aligned_by_overlap = true;
  f.changed = false;
  f.last_attempt = 10.0;
  f.last_refine = 10.0;
  f.own_size_at_attempt = 30;
  f.map_size_at_attempt = 20;
  return f;
}

std::vector<Turn> Turns(const std::vector<PeerFacts>& facts, double now, std::size_t own = 30,
                        const ExchangeOptions& o = Options(), PeerKey first = {}) {
  return PlanTurns(facts, own, now, first, o).turns;
}

TEST(PeerSchedule, FreshPeersAreAlignedWithinTheBudgetAndTheNextUpdateStartsWhereItStopped) {
  const std::vector<PeerFacts> facts = {Fresh(1), Fresh(2), Fresh(3), Fresh(4)};
  const PeerSchedule s = PlanTurns(facts, 30, 0.0, {}, Options());
  ASSERT_EQ(s.turns.size(), 2u);
  EXPECT_EQ(s.turns[0], (Turn{{1, 1}, TurnKind::kAlign, true}));
  EXPECT_EQ(s.turns[1], (Turn{{2, 1}, TurnKind::kAlign, true}));
  ASSERT_TRUE(s.next_turn);
  EXPECT_EQ(*s.next_turn, (PeerKey{3, 1}));
  // Round robin: the next update starts at peer 3 and wraps around.
  const std::vector<Turn> next = Turns(facts, 0.0, 30, Options(), *s.next_turn);
  ASSERT_EQ(next.size(), 2u);
  EXPECT_EQ(next[0].key, (PeerKey{3, 1}));
  EXPECT_EQ(next[1].key, (PeerKey{4, 1}));
}

// The full alignments per update grow with the peers, one per peers_per_alignment, so that each
// peer's turn comes as often in a swarm of 128 as of 64; never below max_alignments_per_update.
TEST(PeerSchedule, TheAlignmentBudgetGrowsWithThePeers) {
  ExchangeOptions o = Options();  // at least 2
  o.peers_per_alignment = 16;
  const auto aligns = [&](int peers, const ExchangeOptions& with) {
    std::vector<PeerFacts> facts;
    for (int r = 1; r <= peers; ++r) facts.push_back(Fresh(static_cast<RobotId>(r)));
    EXPECT_EQ(AlignmentBudget(facts, with), static_cast<int>(Turns(facts, 0.0, 30, with).size()));
    return AlignmentBudget(facts, with);
  };
  EXPECT_EQ(aligns(5, o), 2);
  EXPECT_EQ(aligns(32, o), 2);
  EXPECT_EQ(aligns(33, o), 3);
  EXPECT_EQ(aligns(64, o), 4);
  EXPECT_EQ(aligns(127, o), 8);
  o.peers_per_alignment = 0;  // never more
  EXPECT_EQ(aligns(127, o), 2);
  // Peers without a map, and our own earlier incarnations in our frame, are not counted.
  o.peers_per_alignment = 16;
  std::vector<PeerFacts> facts;
  for (int r = 1; r <= 40; ++r) facts.push_back(Fresh(static_cast<RobotId>(r)));
  EXPECT_EQ(AlignmentBudget(facts, o), 3);
  for (int r = 0; r < 8; ++r) facts[static_cast<std::size_t>(r)].has_map = false;
  facts[8].aligned = facts[8].exact = true;
  EXPECT_EQ(AlignmentBudget(facts, o), 2);
}

TEST(PeerSchedule, AnAttemptWaitsForTheAlignPeriodAndForAChange) {
  PeerFacts f = Fresh(1);
  f.last_attempt = 10.0;
  f.own_size_at_attempt = 30;
  f.map_size_at_attempt = 20;
  EXPECT_TRUE(Turns({f}, 14.9).empty());  // within align_period_s
  EXPECT_EQ(Turns({f}, 15.0).size(), 1u);
  f.changed = false;
  EXPECT_TRUE(Turns({f}, 20.0, 30).empty());   // nothing new on either side
  EXPECT_TRUE(Turns({f}, 20.0, 35).empty());   // ours grew by less than a fifth
  EXPECT_EQ(Turns({f}, 20.0, 36).size(), 1u);  // ... by a fifth
  f.silent = true;                             // a silent peer sends nothing better:
  EXPECT_EQ(Turns({f}, 20.0, 31).size(), 1u);  // tried whenever our map changed
  EXPECT_TRUE(Turns({f}, 20.0, 30).empty());   // ... and only then
  f.has_map = false;                           // nothing to align
  EXPECT_TRUE(Turns({f}, 20.0, 36).empty());
}

// Rendezvous fits are weighed within their own budget, round robin with the alignments: a peer
// left without its turn comes first in the next update.
TEST(PeerSchedule, RendezvousTurnsAreBudgetedRoundRobin) {
  ExchangeOptions o = Options();
  o.max_rendezvous_per_update = 2;
  o.align_by = AlignBy::kRendezvous;
  std::vector<PeerFacts> facts;
  for (RobotId r = 1; r <= 5; ++r) {
    facts.push_back(Fresh(r));
    facts.back().rendezvous_waiting = true;
  }
  const PeerSchedule s = PlanTurns(facts, 30, 0.0, {}, o);
  EXPECT_EQ(s.turns, (std::vector<Turn>{{{1, 1}, TurnKind::kRendezvous}, {{2, 1}, TurnKind::kRendezvous}}));
  ASSERT_TRUE(s.next_turn);
  EXPECT_EQ(*s.next_turn, (PeerKey{3, 1}));
  EXPECT_EQ(PlanTurns(facts, 30, 0.0, *s.next_turn, o).turns,
            (std::vector<Turn>{{{3, 1}, TurnKind::kRendezvous}, {{4, 1}, TurnKind::kRendezvous}}));
  // The alignment budget is apart: with both, each peer due gets its full alignment too.
  o.align_by = AlignBy::kBoth;
  o.max_alignments_per_update = 5;
  int align = 0, rendezvous = 0;
  for (const Turn& t : PlanTurns(facts, 30, 0.0, {}, o).turns) {
    align += t.kind == TurnKind::kAlign;
    rendezvous += t.kind == TurnKind::kRendezvous;
  }
  EXPECT_EQ(align, 5);
  EXPECT_EQ(rendezvous, 2);
}

TEST(PeerSchedule, ARendezvousFitIsWeighedFirstAndAlignmentByOverlapFollows) {
  PeerFacts f = Fresh(1);
  f.rendezvous_waiting = true;
  EXPECT_EQ(Turns({f}, 0.0), (std::vector<Turn>{{{1, 1}, TurnKind::kRendezvous}, {{1, 1}, TurnKind::kAlign, true}}));
  ExchangeOptions by_rendezvous = Options();
  by_rendezvous.align_by = AlignBy::kRendezvous;
  EXPECT_EQ(Turns({f}, 0.0, 30, by_rendezvous), (std::vector<Turn>{{{1, 1}, TurnKind::kRendezvous}}));
  ExchangeOptions by_overlap = Options();
  by_overlap.align_by = AlignBy::kOverlap;
  EXPECT_EQ(Turns({f}, 0.0, 30, by_overlap), (std::vector<Turn>{{{1, 1}, TurnKind::kAlign, true}}));
}

TEST(PeerSchedule, AnAlignedPeerIsVerifiedWhenItSentAMapAndRefinedOtherwise) {
  PeerFacts f = Aligned(1);
  EXPECT_TRUE(Turns({f}, 14.0).empty());  // refine_period_s not reached
  EXPECT_EQ(Turns({f}, 15.0), (std::vector<Turn>{{{1, 1}, TurnKind::kRefine}}));
  f.changed = true;
  EXPECT_EQ(Turns({f}, 12.0), (std::vector<Turn>{{{1, 1}, TurnKind::kVerify}}));
  f.stale = true;  // its contribution stays as verified
  EXPECT_TRUE(Turns({f}, 15.0).empty());
  ExchangeOptions no_refine = Options();
  no_refine.refine_period_s = 0.0;
  f = Aligned(1);
  EXPECT_TRUE(Turns({f}, 100.0, 30, no_refine).empty());
}

TEST(PeerSchedule, GrowthOrAnUnconfirmedAnswerBringsARealignmentBeforeTheVerification) {
  PeerFacts f = Aligned(1);
  f.changed = true;
  EXPECT_EQ(Turns({f}, 15.0, 36), (std::vector<Turn>{{{1, 1}, TurnKind::kRealign}, {{1, 1}, TurnKind::kVerify}}));
  EXPECT_EQ(Turns({f}, 14.0, 36), (std::vector<Turn>{{{1, 1}, TurnKind::kVerify}}));  // within align_period_s
  f.map_size = 24;  // the peer's map grew by a fifth, ours did not
  EXPECT_EQ(Turns({f}, 15.0, 30).front().kind, TurnKind::kRealign);
  f.map_size = 20;
  f.awaiting_confirmation = true;  // a disagreeing answer waits: any change makes the next one due
  EXPECT_EQ(Turns({f}, 15.0, 31).front().kind, TurnKind::kRealign);
  f.stale = true;  // a stale peer's map is still placed afresh on our growing map, never verified
  EXPECT_EQ(Turns({f}, 15.0, 36), (std::vector<Turn>{{{1, 1}, TurnKind::kRealign}}));
  ExchangeOptions off = Options();
  off.test_only.realign_on_growth = false;
  f = Aligned(1);
  f.changed = true;
  EXPECT_EQ(Turns({f}, 15.0, 36, off), (std::vector<Turn>{{{1, 1}, TurnKind::kVerify}}));
}

// An earlier own incarnation placed by continuity is in our own frame: never realigned,
// verified or refined, however both maps grow.
TEST(PeerSchedule, AnExactPlacementIsNeverRevisited) {
  PeerFacts f = Aligned(3);
  f.aligned_by_overlap = false;
  f.exact = true;
  f.stale = true;
  f.changed = true;
  f.own_size_at_attempt = 0;
  f.map_size_at_attempt = 0;
  f.last_attempt = -1e300;
  f.last_refine = -1e300;
  EXPECT_EQ(Turns({f}, 100.0, 80), std::vector<Turn>{});
  f.exact = false;  // the same facts placed by overlap: realigned
  EXPECT_EQ(Turns({f}, 100.0, 80), (std::vector<Turn>{{{3, 1}, TurnKind::kRealign}}));
}

// An unaligned incarnation whose map a later one in its frame carries is not searched: in a
// restart storm a survivor tried every silent incarnation whenever its own map changed (116
// searches of six dead incarnations of one robot in one run) and one gave a false 92 degrees.
// A rendezvous fit of it is still weighed.
TEST(PeerSchedule, AnIncarnationCarriedByALaterOneIsNotSearched) {
  PeerFacts dead = Fresh(3, 1), live = Fresh(3, 2);
  dead.silent = dead.stale = true;
  EXPECT_EQ(Turns({dead, live}, 0.0),
            (std::vector<Turn>{{{3, 1}, TurnKind::kAlign, true}, {{3, 2}, TurnKind::kAlign, true}}));
  dead.carried = true;
  EXPECT_EQ(Turns({dead, live}, 0.0), (std::vector<Turn>{{{3, 2}, TurnKind::kAlign, true}}));
  dead.rendezvous_waiting = true;
  EXPECT_EQ(Turns({dead, live}, 0.0),
            (std::vector<Turn>{{{3, 1}, TurnKind::kRendezvous}, {{3, 2}, TurnKind::kAlign, true}}));
}

TEST(PeerSchedule, RealignmentsShareTheBudgetWithFirstAlignments) {
  PeerFacts a = Aligned(1), b = Aligned(2);
  a.changed = b.changed = true;
  const std::vector<PeerFacts> facts = {a, b, Fresh(3)};
  const PeerSchedule s = PlanTurns(facts, 36, 15.0, {}, Options());
  // Two realignments use the budget of two; the fresh peer waits and is first next time.
  EXPECT_EQ(s.turns, (std::vector<Turn>{{{1, 1}, TurnKind::kRealign},
                                        {{1, 1}, TurnKind::kVerify},
                                        {{2, 1}, TurnKind::kRealign},
                                        {{2, 1}, TurnKind::kVerify}}));
  ASSERT_TRUE(s.next_turn);
  EXPECT_EQ(*s.next_turn, (PeerKey{3, 1}));
}

TEST(PeerSchedule, RelaysAreJudgedNeverJudgedFirstThenByGrowthWithinTheBudgets) {
  std::vector<PeerFacts> facts;
  for (RobotId r = 1; r <= 6; ++r) {
    PeerFacts f = Aligned(r);
    f.has_global = true;
    f.witness = true;
    f.global_judged = r != 5;  // 5 never judged
    f.global_newer = r != 6;   // 6's global map was judged as it is
    f.global_growth = static_cast<long>(r);
    f.last_judged = 10.0;
    facts.push_back(f);
  }
  ExchangeOptions o = Options();
  o.max_relay_checks_per_update = 3;
  PeerSchedule s = PlanTurns(facts, 30, 11.0, {}, o);
  EXPECT_EQ(s.relay_turns, (std::set<PeerKey>{{5, 1}, {4, 1}, {3, 1}}));
  // A relay's turn verifies the peer, judging its global map, though it sent no local map.
  for (const Turn& t : s.turns) {
    EXPECT_EQ(t.kind, TurnKind::kVerify);
    EXPECT_TRUE(t.judge_relay);
    EXPECT_TRUE(s.relay_turns.count(t.key));
  }
  // Six witnesses and at most 12 comparisons: two relays.
  o.max_relay_comparisons_per_update = 12;
  EXPECT_EQ(PlanTurns(facts, 30, 11.0, {}, o).relay_turns, (std::set<PeerKey>{{5, 1}, {4, 1}}));
  // ... but always one.
  o.max_relay_comparisons_per_update = 1;
  EXPECT_EQ(PlanTurns(facts, 30, 11.0, {}, o).relay_turns.size(), 1u);
  o.relay_global_maps = false;
  EXPECT_TRUE(PlanTurns(facts, 30, 11.0, {}, o).relay_turns.empty());
}

// Over seeded random tables: the budget holds, every turn names a peer with a map, first
// alignments go to unaligned peers and the rest to aligned ones, a peer's turns come together,
// and the schedule is a function of its input (the same table gives the same turns).
TEST(PeerSchedule, PropertiesOverSeededRandomTables) {
  std::mt19937_64 rng(9);
  std::bernoulli_distribution coin(0.5);
  std::uniform_int_distribution<int> size(0, 60), count(0, 12);
  std::uniform_real_distribution<double> when(0.0, 30.0);
  for (int trial = 0; trial < 500; ++trial) {
    std::vector<PeerFacts> facts;
    const int n = count(rng);
    for (int i = 0; i < n; ++i) {
      PeerFacts f;
      f.key = {static_cast<RobotId>(1 + i / 2), static_cast<std::uint32_t>(1 + i % 2)};
      f.has_map = coin(rng);
      f.aligned = coin(rng);
      f.aligned_by_overlap = coin(rng);
      f.awaiting_confirmation = coin(rng);
      f.stale = coin(rng) && coin(rng);
      f.silent = f.stale || coin(rng);
      f.changed = coin(rng);
      f.rendezvous_waiting = coin(rng);
      f.carried = coin(rng) && coin(rng);
      f.last_attempt = when(rng);
      f.last_refine = when(rng);
      f.map_size = static_cast<std::size_t>(size(rng));
      f.own_size_at_attempt = static_cast<std::size_t>(size(rng));
      f.map_size_at_attempt = static_cast<std::size_t>(size(rng));
      f.has_global = coin(rng);
      f.global_judged = coin(rng);
      f.global_newer = coin(rng);
      f.global_growth = size(rng) - 30;
      f.witness = coin(rng);
      facts.push_back(f);
    }
    ExchangeOptions o = Options();
    o.max_alignments_per_update = 1 + trial % 4;
    o.max_rendezvous_per_update = 1 + trial % 3;
    const PeerKey first{static_cast<RobotId>(trial % 7), 1};
    const double now = 30.0;
    const std::size_t own = static_cast<std::size_t>(size(rng));
    const PeerSchedule s = PlanTurns(facts, own, now, first, o);
    EXPECT_EQ(s.turns, PlanTurns(facts, own, now, first, o).turns);
    int full = 0, rendezvous = 0;
    std::set<PeerKey> done;
    std::optional<PeerKey> last;
    for (const Turn& t : s.turns) {
      const auto f = std::find_if(facts.begin(), facts.end(), [&](const PeerFacts& x) { return x.key == t.key; });
      ASSERT_NE(f, facts.end());
      EXPECT_TRUE(f->has_map);
      if (t.kind == TurnKind::kAlign || t.kind == TurnKind::kRendezvous) {
        EXPECT_FALSE(f->aligned);
      }
      if (t.kind == TurnKind::kAlign) {
        EXPECT_FALSE(f->carried);
      }
      if (t.kind == TurnKind::kRealign || t.kind == TurnKind::kVerify || t.kind == TurnKind::kRefine) {
        EXPECT_TRUE(f->aligned);
      }
      if (t.kind == TurnKind::kVerify || t.kind == TurnKind::kRefine) {
        EXPECT_FALSE(f->stale);
      }
      full += t.kind == TurnKind::kAlign || t.kind == TurnKind::kRealign;
      rendezvous += t.kind == TurnKind::kRendezvous;
      if (last != t.key) {
        EXPECT_FALSE(done.count(t.key)) << "a peer's turns come together";
        done.insert(t.key);
      }
      last = t.key;
    }
    EXPECT_LE(full, o.max_alignments_per_update);
    EXPECT_LE(rendezvous, o.max_rendezvous_per_update);
    EXPECT_LE(static_cast<int>(s.relay_turns.size()), o.max_relay_checks_per_update);
  }
}

// A relayed chain (the joining back-end's) is aligned when never tried, when either map grew by
// retry_growth, or align_period_s after an accepted alignment waiting to be confirmed; after a
// failed try both are doubled (once: two failures wait as long as one).
TEST(PeerSchedule, ARelayedChainIsTriedAgainLaterAfterAFailedTry) {
  ExchangeOptions o;  // retry_growth 0.2, align_period_s 5
  RelayedAlignmentFacts f;
  EXPECT_TRUE(RelayedAlignmentDue(f, 10, 100, 0.0, o));  // never tried
  f.tried_at = 10.0;
  f.tried_size = 50;
  f.tried_target = 100;
  // Tried and not accepted but once before (failures 0: the last one was accepted or none failed).
  EXPECT_FALSE(RelayedAlignmentDue(f, 59, 119, 100.0, o));
  EXPECT_TRUE(RelayedAlignmentDue(f, 60, 100, 11.0, o));
  EXPECT_TRUE(RelayedAlignmentDue(f, 50, 120, 11.0, o));
  for (int failures : {1, 2, 7}) {
    f.failures = failures;
    EXPECT_FALSE(RelayedAlignmentDue(f, 69, 139, 100.0, o)) << failures;
    EXPECT_TRUE(RelayedAlignmentDue(f, 70, 100, 11.0, o)) << failures;
    EXPECT_TRUE(RelayedAlignmentDue(f, 50, 140, 11.0, o)) << failures;
  }
  // An accepted alignment waiting for a second: the same maps an align period later, or two
  // after a failed confirmation.
  f.candidate = true;
  f.failures = 0;
  EXPECT_FALSE(RelayedAlignmentDue(f, 50, 100, 14.9, o));
  EXPECT_TRUE(RelayedAlignmentDue(f, 50, 100, 15.0, o));
  f.failures = 1;
  EXPECT_FALSE(RelayedAlignmentDue(f, 50, 100, 19.9, o));
  EXPECT_TRUE(RelayedAlignmentDue(f, 50, 100, 20.0, o));
}

}  // namespace
}  // namespace mapmesh
