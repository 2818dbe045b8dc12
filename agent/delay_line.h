#pragma once
// The radio's latency at the receiver (U1, radio.latency_s): a message the radio gate passed
// waits here from when it reached the agent until it arrives over the link
// (RadioGate::Arrival: its stamp, the link's latency and its transmission time), then the agent
// takes it as if it had just come. Lockstep asks at each exchange tick with the tick's stamp,
// real time at each odometry interval with the agent's clock; so a latency below a tick's
// period changes nothing in lockstep, where a peer's map waits for the next tick anyway.
//
// Bounded whatever the latency and the swarm: beyond max_messages or max_bytes held a message
// is dropped (counted). Messages come out in the order of their arrival, then of their
// holding. Pure: no DDS, clocks or threads.

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "common/types/messages.h"

namespace mapmesh {

struct DelayLineOptions {
  std::size_t max_messages = 1u << 16;
  std::size_t max_bytes = 256u << 20;  // the maps' wire bytes
};

class DelayLine {
 public:
  struct HeldMap {
    MapMessage map;
    std::string writer;  // its DDS writer, as offered
    std::size_t bytes = 0;
  };
  using Message = std::variant<HeldMap, Sighting>;

  explicit DelayLine(const DelayLineOptions& options = {}) : options_(options) {}

  // Holds a map (of `bytes` on the wire) or a sighting until `arrival`; false, and dropped, when
  // holding it would pass a bound.
  bool Hold(double arrival, MapMessage map, std::string writer, std::size_t bytes);
  bool Hold(double arrival, const Sighting& sighting);

  // The messages that have arrived by `now` (arrival <= now), taken out in order.
  std::vector<Message> TakeArrived(double now);

  std::size_t size() const { return held_.size(); }
  std::size_t bytes() const { return bytes_; }
  std::uint32_t dropped() const { return dropped_; }

 private:
  bool Room(std::size_t bytes);

  DelayLineOptions options_;
  std::map<std::pair<double, std::uint64_t>, Message> held_;  // by (arrival, holding order)
  std::uint64_t next_ = 0;
  std::size_t bytes_ = 0;
  std::uint32_t dropped_ = 0;
};

}  // namespace mapmesh
