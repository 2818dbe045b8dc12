#pragma once
// Typed writers and readers over core value types: Writer<Odometry> writes an Odometry,
// Reader<Odometry> takes them, converting through convert.h.

#include <string>
#include <vector>

#include "common/transport/convert.h"
#include "common/transport/dds.h"

namespace mapmesh::transport {

template <typename T>
class Writer {
 public:
  Writer(const Participant& p, const std::string& topic, const Qos& qos)
      : topic_(p, Wire<T>::Descriptor(), topic, qos), raw_(p, topic_, qos) {}
  void Write(const T& value) {
    auto msg = ToMsg(value, scratch_);
    raw_.Write(&msg);
  }
  // Writes, then unregisters the instance: readers see this writer's sample, but the
  // instance's liveliness keeps following its other writers.
  void WriteAndUnregister(const T& value) {
    auto msg = ToMsg(value, scratch_);
    raw_.Write(&msg);
    raw_.Unregister(&msg);
  }
  const RawWriter& raw() const { return raw_; }

 private:
  Topic topic_;
  RawWriter raw_;
  MsgScratch scratch_;
};

// One taken sample. valid is false for a pure instance-state change (for example the
// writer went away); then only the key fields of value are meaningful.
template <typename T>
struct Sample {
  T value;
  bool valid = true;
  bool alive = true;                      // instance state ALIVE
  dds_instance_handle_t publication = 0;  // the writer (see WriterPartitions)
};

template <typename T>
class Reader {
 public:
  Reader(const Participant& p, const std::string& topic, const Qos& qos)
      : topic_(p, Wire<T>::Descriptor(), topic, qos), raw_(p, topic_, qos) {}

  // Takes everything available now, in reception order.
  std::vector<Sample<T>> Take() {
    constexpr int kBatch = 64;
    std::vector<Sample<T>> out;
    while (true) {
      void* buf[kBatch] = {};
      dds_sample_info_t info[kBatch];
      const dds_return_t n = Check(dds_take(raw_.get(), buf, info, kBatch, kBatch), "dds_take");
      for (dds_return_t i = 0; i < n; ++i) {
        using Msg = typename Wire<T>::Msg;
        out.push_back({FromMsg(*static_cast<const Msg*>(buf[i])), info[i].valid_data,
                       info[i].instance_state == DDS_IST_ALIVE, info[i].publication_handle});
      }
      if (n > 0) Check(dds_return_loan(raw_.get(), buf, n), "dds_return_loan");
      if (n < kBatch) break;
    }
    return out;
  }
  const RawReader& raw() const { return raw_; }

 private:
  Topic topic_;
  RawReader raw_;
};

}  // namespace mapmesh::transport
