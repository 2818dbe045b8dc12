#include "common/transport/shutdown.h"

#include <pthread.h>
#include <signal.h>

namespace mapmesh::transport {
namespace {

sigset_t WatchedSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGHUP);   // a closed terminal: outputs written as for SIGTERM
  sigaddset(&set, SIGUSR2);  // internal: stops the watcher
  return set;
}

}  // namespace

ShutdownSignal::ShutdownSignal() {
  const sigset_t set = WatchedSignals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

ShutdownSignal::~ShutdownSignal() {
  if (watcher_.joinable()) {
    pthread_kill(watcher_.native_handle(), SIGUSR2);
    watcher_.join();
  }
}

void ShutdownSignal::Watch(const GuardCondition* guard) {
  const dds_entity_t g = guard ? guard->get() : 0;
  watcher_ = std::thread([this, g] {
    const sigset_t set = WatchedSignals();
    int sig = 0;
    if (sigwait(&set, &sig) != 0 || sig == SIGUSR2) return;
    signal_.store(sig);
    if (g > 0) dds_set_guardcondition(g, true);
  });
}

}  // namespace mapmesh::transport
