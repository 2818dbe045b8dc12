#include "common/map/submap_digest.h"

#include <openssl/sha.h>

#include <array>

namespace mapmesh {

std::uint64_t SubmapDigest(std::span<const std::uint8_t> bytes) {
  std::array<unsigned char, SHA256_DIGEST_LENGTH> h{};
  SHA256(bytes.data(), bytes.size(), h.data());
  std::uint64_t d = 0;
  for (int i = 0; i < 8; ++i) d = (d << 8) | h[static_cast<std::size_t>(i)];
  return d;
}

}  // namespace mapmesh
