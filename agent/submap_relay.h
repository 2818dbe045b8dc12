#pragma once
// SubmapRelay: the closed submaps an agent holds and which of them it sends (issue J1); it reads
// the submaps offered to it, its peers' advertisements and the peers it is told are in range,
// and changes only itself.
//
// Anti-entropy by identity: each local map advertises the chains its publisher holds (per robot
// incarnation, the submaps from index 0 without a gap). A submap goes out when a peer in range
// advertised a chain that lacks it, and goes out again only after resend_after_s: one lost on
// the way is sent again, one received is not once the peer's advertisement shows it. A submap
// just heard from another robot (new or not) is not sent on the peer's word until the peer
// has advertised since: it most likely heard that robot too, and its next advertisement says
// (a neighbourhood that holds a submap does not send it all at once to the peer that lacks it;
// in lockstep this costs a relay one period per hop). A submap
// relayed on is byte for byte the one its robot sent, so it reaches any number of hops and
// enters every book once (SubmapBook). Decisions depend on the facts given and the scenario
// time only: lockstep runs send the same submaps.
//
// Open submaps (fusion joining): the agent keeps each other robot incarnation's latest open
// submap it took (a later index, or the same one mapped further), its publisher's or relayed.
// One that has not changed for open_silent_after_s is a silent robot's: it goes, as taken, to
// a peer in range whose advertisement holds the chain up to it (count = its index) but not it
// (no open_until, or an earlier one: a peer holding a later open submap of the robot does not
// lack it), again only after resend_after_s. A relayed one is taken only where it continues the
// chain held. A robot's open submap reaches the
// peers of the last agents that heard it, hop by hop, once it falls silent; while it publishes,
// its peers hear it themselves and nothing is relayed. The closed submap of its index replaces
// it. It enters a join only where it continues the chain held, so nothing is counted twice.
//
// Pure: no DDS, clocks or random numbers.

#include <cstdint>
#include <limits>
#include <map>
#include <set>
#include <span>
#include <vector>

#include "agent/peer_state.h"
#include "common/map/submap_book.h"
#include "common/options/submap_relay_options.h"

namespace mapmesh {

class SubmapRelay {
 public:
  explicit SubmapRelay(const SubmapRelayOptions& options) : options_(options) {}

  // kGap: a relayed open submap that does not continue the chain held (AddOpen).
  enum class Offer { kNew, kDuplicate, kConflict, kFull, kGap };
  // One of the agent's own closed submaps. kFull never happens: own submaps always enter.
  // Each offer carries the submap's bytes and the signature they came with (secure runs; empty
  // otherwise), which the relay sends on with them.
  Offer AddOwn(const WireSubmap& submap, std::span<const std::uint8_t> bytes,
               std::span<const std::uint8_t> signature = {});
  // A decoded, validated submap received from a peer (or relayed by one) at scenario time now:
  // kFull when max_held submaps are held, or it would take the peers' submaps beyond
  // max_bytes_held or its chain beyond max_chain_bytes (issue R3: bounded in bytes, not only
  // in count).
  Offer Add(const WireSubmap& submap, std::span<const std::uint8_t> bytes, double now,
            std::span<const std::uint8_t> signature = {});
  // A submap the agent held before a restart (its checkpoint): it enters as held (max_held
  // does not apply: the checkpoint held it), due to any peer that lacks it as an own one is.
  Offer Restore(const WireSubmap& submap, std::span<const std::uint8_t> bytes,
                std::span<const std::uint8_t> signature = {});
  // A peer's advertisement, received at scenario time now; replaces its earlier one. Chains
  // beyond max_chains are ignored.
  void OnAdvert(const PeerKey& from, std::span<const SubmapChain> held, double now);
  // Its owner's word on its own chain (issue R3), from a local map taken from the owner itself
  // (its writer, in range): the chain's count and the digests of its latest closed submaps
  // (indices count - digests.size() .. count - 1; SubmapDigest). A held copy of one of those
  // indices that disagrees is dropped (owner_conflicts), and so is one at or beyond count
  // (ahead_of_owner: the owner has not closed it; in lockstep no relay is ahead of the owner's
  // advertisement, which comes with the submap). A peer's advertisement then shows it lacking
  // and the owner's comes; a later copy that disagrees with a digest the owner advertised is
  // refused (Add: kConflict, owner_conflicts). More digests than count: ignored. Returns the
  // submaps dropped.
  std::size_t OnOwnerAdvert(const PeerKey& owner, std::uint32_t count, std::span<const std::uint64_t> digests);
  // The digests of a robot incarnation's latest closed submaps held without a gap from index 0,
  // at most kOwnDigests (what its owner advertises: MapMessage::own_submap_digests).
  std::vector<std::uint64_t> OwnDigests(const PeerKey& own) const;
  // The chains to advertise (SubmapBook::Chains, with open_until where an open submap is held
  // beyond the chain's closed ones; a chain of which only an open submap is held has count 0,
  // advertised only where max_chains leaves room), at most max_chains.
  std::vector<SubmapChain> Advert() const;

  // Another robot's decoded, validated open submap, from its publisher or relayed, received at
  // scenario time now: kept when it is the first of its robot incarnation, or later (a higher
  // index, or the same mapped further) than the one kept, and no closed submap of its index is
  // held (kDuplicate otherwise, ignored). A relayed one only where it continues the chain held
  // (its index is the ChainLength: kGap otherwise, as a relay sends it); kFull when max_open
  // open ones are kept already.
  Offer AddOpen(const WireSubmap& submap, std::span<const std::uint8_t> bytes, double now, bool relayed = false,
                std::span<const std::uint8_t> signature = {});
  // The bytes kept of a robot incarnation's open submap; null when none.
  const std::vector<std::uint8_t>* OpenBytes(const PeerKey& key) const;
  // The open submaps kept, by robot incarnation (the joining back-end's input).
  const std::map<PeerKey, WireSubmap>& open() const { return open_; }
  // The silent robots' open submaps to relay at scenario time now (see the header), lowest
  // index first, then robot and incarnation; at most send_bytes in all with the `spent` bytes
  // of the closed ones due in the same publication (the first always, when those are none).
  // Marks them sent at now.
  std::vector<const SubmapBlob*> DueOpen(const std::set<RobotId>& in_range, double now, std::size_t spent = 0);
  // The submaps to send at scenario time now: those held that a peer in range (a robot of
  // `in_range` whose advertisement is at most advert_max_age_s old) lacks by an advertisement
  // that came after the submap was last heard, not sent within resend_after_s, the lowest
  // indices first (every chain grows alike), then robot and incarnation; at most send_bytes in
  // all. Marks them sent at now.
  std::vector<const SubmapBlob*> Due(const std::set<RobotId>& in_range, double now);

  const SubmapBook& book() const { return book_; }
  struct Counters {
    std::uint32_t own = 0;                 // own closed submaps entered
    std::uint32_t received_new = 0;        // peers' submaps entered
    std::uint32_t restored = 0;            // submaps entered from the checkpoint (Restore)
    std::uint32_t duplicates = 0;          // ... held already
    std::uint32_t conflicts = 0;           // ... a different submap under a held identity (refused)
    std::uint32_t owner_conflicts = 0;     // held or offered copies that disagreed with their owner's digest (dropped)
    std::uint32_t ahead_of_owner = 0;      // held copies at indices their owner had not closed (dropped)
    std::uint32_t full = 0;                // ... refused, max_held or max_bytes_held reached
    std::uint32_t chain_full = 0;          // ... refused, their chain at max_chain_bytes
    std::uint32_t sent = 0;                // submaps sent (own and relayed, each time)
    std::uint64_t bytes_sent = 0;          // ... their bytes
    std::uint32_t sent_again = 0;          // ... of which sent before (to a peer come into range since, or lost)
    std::uint32_t held_back = 0;           // due ones left for a later publication (send_bytes)
    std::uint64_t debt_paid = 0;           // bytes of later publications' budgets paid for a submap beyond one's
    std::uint32_t open_taken = 0;          // open submaps kept (AddOpen: each later version)
    std::uint32_t open_gaps = 0;           // relayed open submaps refused: not continuing the chain held (kGap)
    std::uint32_t open_relayed = 0;        // silent robots' open submaps sent (DueOpen, each time)
    std::uint64_t open_bytes_relayed = 0;  // ... their bytes
  };
  const Counters& counters() const { return counters_; }

  // Advertisements carry at most this many chains (a robot incarnation per chain).
  static constexpr std::size_t kMaxChains = 4096;
  // An owner advertises the digests of at most this many of its latest closed submaps (8 bytes
  // each): a copy older than that is not checked against its owner.
  static constexpr std::size_t kOwnDigests = 64;

 private:
  struct Advertised {
    std::map<std::pair<RobotId, std::uint32_t>, std::uint32_t> count;  // chain -> submaps held from 0 ...
    std::map<std::pair<RobotId, std::uint32_t>, double> open_until;    // ... and its open one's end, if any
    double at = 0.0;
  };
  struct OpenHeld {
    SubmapBlob blob;
    double changed_at = 0.0;  // scenario time this version was taken
    double sent_at = -std::numeric_limits<double>::infinity();
  };
  // Drops the open submap a closed one of the same identity replaces.
  void CloseOpen(const SubmapId& id);
  SubmapRelayOptions options_;
  SubmapBook book_;
  std::map<PeerKey, Advertised> adverts_;
  std::map<SubmapId, double> sent_at_;         // scenario time each submap was last sent ...
  std::map<SubmapId, double> heard_at_;        // ... and last received from a peer
  std::map<SubmapId, std::uint64_t> digests_;  // each held submap's SubmapDigest
  // Per robot incarnation: its owner's latest advertisement (count, and the digests from index
  // count - size), and the digest of each index it advertised.
  std::map<PeerKey, std::map<std::uint32_t, std::uint64_t>> owner_digests_;
  // Drops a held submap and what is kept about it.
  void Drop(const SubmapId& id);
  std::map<PeerKey, WireSubmap> open_;     // the open submaps kept ...
  std::map<PeerKey, OpenHeld> open_held_;  // ... their bytes and times
  Counters counters_;
  std::size_t own_bytes_ = 0;  // the own closed submaps' bytes in book_ (not bounded)
  std::size_t debt_ = 0;       // bytes sent beyond a publication's budget, not yet paid
  std::size_t paid_ = 0;       // ... of which the latest Due paid
  // Spends `size` bytes of a publication whose budget had `spent` used (first: nothing sent in
  // it yet and its budget whole): whether it goes; beyond the budget becomes debt.
  bool Spend(std::size_t size, std::size_t& spent, bool first);
};

}  // namespace mapmesh
