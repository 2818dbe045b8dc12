#pragma once
// Samples the transport dropped for their size (issue R3): Cyclone drops a sample beyond
// Internal/MaxSampleSize (Session's max_sample_bytes) before it is reassembled, and says so only
// in a warning. OversizeCounter takes Cyclone's log messages for the life of the object, counts
// the drops of samples from other processes' writers ("dropping oversize ... from remote
// writer"), and writes every message to stderr as Cyclone's own sink does. One per process: it
// replaces the process's log sink, and gives it back when destroyed.

#include <atomic>
#include <cstdint>
#include <string_view>

namespace mapmesh::transport {

class OversizeCounter {
 public:
  OversizeCounter();
  ~OversizeCounter();
  OversizeCounter(const OversizeCounter&) = delete;
  OversizeCounter& operator=(const OversizeCounter&) = delete;

  // Samples from other processes dropped so far (Cyclone's threads count them).
  std::uint64_t received() const { return received_.load(std::memory_order_relaxed); }
  // Whether a Cyclone log message reports a received sample dropped for its size.
  static bool IsReceivedOversizeDrop(std::string_view message);

 private:
  static void Sink(void* self, const void* data);
  std::atomic<std::uint64_t> received_{0};
};

}  // namespace mapmesh::transport
