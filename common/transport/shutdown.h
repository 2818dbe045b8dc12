#pragma once
// Turns SIGINT/SIGTERM/SIGHUP into a guard-condition trigger, so a WaitSet loop ends cleanly.
// Construct it first thing in main: it blocks the signals in the calling thread, and every
// thread created afterwards (Cyclone's included) inherits that, so a watcher thread using
// sigwait receives them.

#include <atomic>
#include <thread>

#include "common/transport/dds.h"

namespace mapmesh::transport {

class ShutdownSignal {
 public:
  ShutdownSignal();
  ~ShutdownSignal();
  ShutdownSignal(const ShutdownSignal&) = delete;
  ShutdownSignal& operator=(const ShutdownSignal&) = delete;

  // Starts the watcher; a signal sets requested() and triggers guard (may be null).
  void Watch(const GuardCondition* guard);
  bool requested() const { return signal_.load() != 0; }
  int signal() const { return signal_.load(); }

 private:
  std::atomic<int> signal_{0};
  std::thread watcher_;
};

}  // namespace mapmesh::transport
