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
// Pure: no DDS, clocks or random numbers.

#include <cstdint>
#include <map>
#include <set>
#include <span>
#include <vector>

#include "agent/peer_state.h"
#include "common/map/submap_book.h"

namespace mapmesh {

struct SubmapRelayOptions {
  std::size_t send_bytes = 65536;  // agent.submap_send_bytes: submap bytes per publication (the first one due
                                   // always goes, whatever its size)
  double resend_after_s = 0.0;     // agent.submap_resend_after_s: a submap sent goes again no sooner (0: 3 map
                                   // periods, a round trip of advertisements and one to spare)
  std::size_t max_held = 20000;    // agent.max_submaps_held: submaps held at most (own ones always)
  double advert_max_age_s = 0.0;   // a peer's advertisement counts this long after it arrived (0: 3 map periods)
};

class SubmapRelay {
 public:
  explicit SubmapRelay(const SubmapRelayOptions& options) : options_(options) {}

  enum class Offer { kNew, kDuplicate, kConflict, kFull };
  // One of the agent's own closed submaps. kFull never happens: own submaps always enter.
  Offer AddOwn(const WireSubmap& submap, std::span<const std::uint8_t> bytes);
  // A decoded, validated submap received from a peer (or relayed by one) at scenario time now.
  Offer Add(const WireSubmap& submap, std::span<const std::uint8_t> bytes, double now);
  // A submap the agent held before a restart (its checkpoint): it enters as held (max_held
  // does not apply: the checkpoint held it), due to any peer that lacks it as an own one is.
  Offer Restore(const WireSubmap& submap, std::span<const std::uint8_t> bytes);
  // A peer's advertisement, received at scenario time now; replaces its earlier one. Chains
  // beyond max_chains are ignored.
  void OnAdvert(const PeerKey& from, std::span<const SubmapChain> held, double now);
  // The chains to advertise (SubmapBook::Chains), at most max_chains.
  std::vector<SubmapChain> Advert() const;
  // The submaps to send at scenario time now: those held that a peer in range (a robot of
  // `in_range` whose advertisement is at most advert_max_age_s old) lacks by an advertisement
  // that came after the submap was last heard, not sent within resend_after_s, the lowest
  // indices first (every chain grows alike), then robot and incarnation; at most send_bytes in
  // all. Marks them sent at now.
  std::vector<const std::vector<std::uint8_t>*> Due(const std::set<RobotId>& in_range, double now);

  const SubmapBook& book() const { return book_; }
  struct Counters {
    std::uint32_t own = 0;           // own closed submaps entered
    std::uint32_t received_new = 0;  // peers' submaps entered
    std::uint32_t restored = 0;      // submaps entered from the checkpoint (Restore)
    std::uint32_t duplicates = 0;    // ... held already
    std::uint32_t conflicts = 0;     // ... a different submap under a held identity (refused)
    std::uint32_t full = 0;          // ... refused, max_held reached
    std::uint32_t sent = 0;          // submaps sent (own and relayed, each time)
    std::uint64_t bytes_sent = 0;    // ... their bytes
    std::uint32_t sent_again = 0;    // ... of which sent before (to a peer come into range since, or lost)
    std::uint32_t held_back = 0;     // due ones left for a later publication (send_bytes)
  };
  const Counters& counters() const { return counters_; }

  // Advertisements carry at most this many chains (a robot incarnation per chain).
  static constexpr std::size_t kMaxChains = 4096;

 private:
  struct Advertised {
    std::map<std::pair<RobotId, std::uint32_t>, std::uint32_t> count;  // chain -> submaps held from 0
    double at = 0.0;
  };
  SubmapRelayOptions options_;
  SubmapBook book_;
  std::map<PeerKey, Advertised> adverts_;
  std::map<SubmapId, double> sent_at_;   // scenario time each submap was last sent ...
  std::map<SubmapId, double> heard_at_;  // ... and last received from a peer
  Counters counters_;
};

}  // namespace mapmesh
