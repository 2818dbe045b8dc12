#pragma once
// Which link tables and exchange ticks an agent takes: only the run's feeder's. It reads a
// sample's writer (its partitions and handle) and changes only which writer it trusts.
//
// The feeder writes them in its own partition (kFeederPartition); an agent's reader also
// matches every other partition, so that a table or tick from anyone else arrives, is refused
// and is counted. The first writer in the feeder's partition whose sample is taken is trusted
// from then on (by its GUID, which it keeps when it is matched anew after a lapsed lease), and a
// second writer there is refused: a participant that joins a plain run later cannot speak for
// the feeder. What a plain run trusts is in docs/SECURITY.md; under
// --secure only the feeder's certificate may write in that partition.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace mapmesh::transport {

inline constexpr const char* kFeederPartition = "feeder";

class FeederSource {
 public:
  enum class Verdict { kFeeder, kOutsidePartition, kSecondWriter };

  // Judges one sample from the writer whose GUID is `writer` and whose partitions are
  // `writer_partitions` (either nullptr: the writer is unknown).
  Verdict Judge(const std::vector<std::string>* writer_partitions, const std::string* writer) {
    if (!writer || !writer_partitions || writer_partitions->size() != 1 ||
        writer_partitions->front() != kFeederPartition) {
      ++refused_;
      return Verdict::kOutsidePartition;
    }
    if (!writer_) writer_ = *writer;
    if (*writer_ != *writer) {
      ++refused_;
      return Verdict::kSecondWriter;
    }
    return Verdict::kFeeder;
  }
  // Samples refused so far, for both reasons.
  std::uint64_t refused() const { return refused_; }

 private:
  std::optional<std::string> writer_;
  std::uint64_t refused_ = 0;
};

}  // namespace mapmesh::transport
