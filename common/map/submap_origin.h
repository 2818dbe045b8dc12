#pragma once
// Who vouches for a submap's origin (issue R3). A submap's identity (robot, incarnation,
// index) is a claim its bytes make; relays carry any robot's submaps, so the map a submap
// rides on says nothing of where it came from. In a secure run each agent signs its own
// submaps (closed and open) with its identity's key, every receiver and relay checks the
// signature against the certificate of the robot the submap claims, and relays send the
// signature on with the bytes, unchanged. A plain run has no origin (a null SubmapOrigin*):
// a submap is taken on the word of the map it rides on.
//
// An interface only: the secure runs' is transport::SubmapSigner (OpenSSL, the run's DDS
// Security identities); tests give their own.

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "common/types/messages.h"

namespace mapmesh {

// Signatures longer than this are refused unread (a P-256 ECDSA signature takes at most 72
// bytes, an RSA-4096 one 512).
inline constexpr std::size_t kMaxSubmapSignatureBytes = 1024;

class SubmapOrigin {
 public:
  enum class Verdict {
    kValid,          // signed by the robot the submap claims
    kUnsigned,       // no signature (or one longer than kMaxSubmapSignatureBytes)
    kUnknownSigner,  // no certificate of the run's authority for that robot
    kForged,         // a signature that is not that robot's over these bytes
  };
  virtual ~SubmapOrigin() = default;
  // The agent's own signature over one of its submaps' bytes.
  virtual std::vector<std::uint8_t> Sign(std::span<const std::uint8_t> bytes) = 0;
  // Whether `signature` is robot `origin`'s over `bytes`. Deterministic in its inputs.
  virtual Verdict Verify(RobotId origin, std::span<const std::uint8_t> bytes,
                         std::span<const std::uint8_t> signature) = 0;
};

std::string_view ToString(SubmapOrigin::Verdict v);

}  // namespace mapmesh
