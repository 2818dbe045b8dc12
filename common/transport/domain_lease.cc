#include "common/transport/domain_lease.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace mapmesh::transport {

DomainLease::DomainLease() {
  const std::string dir = "/tmp/mapmesh-domains";
  ::mkdir(dir.c_str(), 0777);
  ::chmod(dir.c_str(), 0777);
  const int n = kLastLeasedDomain - kFirstLeasedDomain + 1;
  const int start = static_cast<int>(::getpid()) % n;
  for (int k = 0; k < n; ++k) {
    const int id = kFirstLeasedDomain + (start + k) % n;
    const std::string path = dir + "/" + std::to_string(id) + ".lock";
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      id_ = id;
      fd_ = fd;
      return;
    }
    ::close(fd);
  }
  throw std::runtime_error("no free DDS domain id in /tmp/mapmesh-domains");
}

DomainLease::~DomainLease() {
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace mapmesh::transport
