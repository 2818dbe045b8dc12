#pragma once
// A recorded feed: every batch a source produced, in a compact binary file, so tests and
// the in-process lab can replay a stream without DDS. The same scenario and seed give a
// byte-identical file.

#include <cstdint>
#include <string>
#include <vector>

#include "sim_feeder/feed_source.h"

namespace mapmesh {

// Appends batches to a file (little-endian; format "MMREC1").
class RecordingWriter {
 public:
  // Throws std::runtime_error if the file cannot be created.
  explicit RecordingWriter(const std::string& path);
  ~RecordingWriter();
  void Write(const FeedBatch& batch);
  // Flushes and closes; throws std::runtime_error on a write error.
  void Close();

 private:
  std::string path_;
  std::FILE* f_ = nullptr;
  std::vector<std::uint8_t> buf_;
};

// Reads a whole recording; throws std::runtime_error naming the file on a malformed one.
std::vector<FeedBatch> ReadRecording(const std::string& path);

}  // namespace mapmesh
