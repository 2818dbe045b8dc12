#pragma once
// Picks a DDS domain id nobody else on this host is using, and holds it: an exclusive
// flock on /tmp/mapmesh-domains/<id>.lock for as long as the lease lives. scripts/swarm
// uses the same files, so parallel runs and parallel tests never share a domain.

namespace mapmesh::transport {

// Domain ids handed out: their Cyclone ports (7400 + 250 * id + ...) stay below the
// Linux ephemeral port range.
inline constexpr int kFirstLeasedDomain = 1;
inline constexpr int kLastLeasedDomain = 97;

class DomainLease {
 public:
  // Takes the first free id in the range, starting at a pid-dependent offset.
  // Throws std::runtime_error when every id is taken.
  DomainLease();
  ~DomainLease();
  DomainLease(const DomainLease&) = delete;
  DomainLease& operator=(const DomainLease&) = delete;
  int id() const { return id_; }

 private:
  int id_ = -1;
  int fd_ = -1;
};

}  // namespace mapmesh::transport
