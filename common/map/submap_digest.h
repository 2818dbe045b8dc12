#pragma once
// A closed submap's digest (issue R3): the first 8 bytes of the SHA-256 of its encoded bytes,
// big-endian. An owner advertises those of its own chain (MapMessage::own_submap_digests), so
// that a holder hearing it can tell a copy that is not the owner's from one that is: a relay
// that wants a forged submap kept must find bytes with the genuine one's digest, a second
// preimage of 64 bits (FNV-1a, wire::Fnv1a64, is for telling runs apart, not forgeries).

#include <cstdint>
#include <span>

namespace mapmesh {

std::uint64_t SubmapDigest(std::span<const std::uint8_t> bytes);

}  // namespace mapmesh
