#pragma once
// SubmapRelayOptions: the closed and open submaps an agent holds and relays (agent/submap_relay.h,
// issue J1): the scenario's agent.submap_* keys, read by ExchangeOptions.

#include <cstddef>

namespace mapmesh {

struct SubmapRelayOptions {
  std::size_t send_bytes = 65536;         // agent.submap_send_bytes: submap bytes per publication (the first one due
                                          // goes whatever its size; what it takes beyond is paid by the next ones)
  double resend_after_s = 0.0;            // agent.submap_resend_after_s: a submap sent goes again no sooner (0: 3 map
                                          // periods, a round trip of advertisements and one to spare)
  std::size_t max_held = 20000;           // agent.max_submaps_held: submaps held at most (own ones always)
  std::size_t max_submap_bytes = 262144;  // agent.max_submap_bytes: a peer's submap longer is refused unread (the
                                          // agent's node; 178 landmarks, twice the densest shipped world's)
  std::size_t max_bytes_held = std::size_t{96} << 20;   // agent.max_submap_bytes_held: peers' closed submaps' bytes
  std::size_t max_chain_bytes = std::size_t{32} << 20;  // agent.max_chain_bytes: ... of one robot incarnation's
  double advert_max_age_s = 0.0;     // a peer's advertisement counts this long after it arrived (0: 3 map periods)
  double open_silent_after_s = 0.0;  // an open submap unchanged this long is relayed (0: agent.silent_after_s)
  std::size_t max_open = 0;  // open submaps kept at most (the agent's: robots x agent.max_incarnations; 0: max_held)
};

}  // namespace mapmesh
