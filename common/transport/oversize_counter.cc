#include "common/transport/oversize_counter.h"

#include <dds/dds.h>

#include <cstdio>

namespace mapmesh::transport {

OversizeCounter::OversizeCounter() {
  dds_set_log_sink([](void* self, const dds_log_data_t* d) { Sink(self, d); }, this);
}

OversizeCounter::~OversizeCounter() { dds_set_log_sink(nullptr, nullptr); }

bool OversizeCounter::IsReceivedOversizeDrop(std::string_view message) {
  return message.find("dropping oversize") != std::string_view::npos &&
         message.find("from remote writer") != std::string_view::npos;
}

void OversizeCounter::Sink(void* self, const void* data) {
  const auto* d = static_cast<const dds_log_data_t*>(data);
  const std::string_view message(d->message, d->size);
  if (IsReceivedOversizeDrop(message)) {
    static_cast<OversizeCounter*>(self)->received_.fetch_add(1, std::memory_order_relaxed);
  }
  std::fwrite(message.data(), 1, message.size(), stderr);
  if (message.empty() || message.back() != '\n') std::fputc('\n', stderr);
}

}  // namespace mapmesh::transport
