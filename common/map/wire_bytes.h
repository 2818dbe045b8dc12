#pragma once
// Little-endian fixed-size values in a byte buffer, for the wire codecs (map_codec, submap_codec).

#include <bit>
#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

namespace mapmesh::wire {

static_assert(std::endian::native == std::endian::little, "the codecs assume a little-endian host");

// Appends v's bytes.
template <typename T>
void Put(std::vector<std::uint8_t>& out, T v) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.insert(out.end(), b, b + sizeof(T));
}

// The value whose bytes start at p.
template <typename T>
T Get(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

// FNV-1a, 64 bits, of the bytes: a short name for a payload in the records (which submap a
// robot holds), not a check against forgery.
inline std::uint64_t Fnv1a64(std::span<const std::uint8_t> bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (std::uint8_t b : bytes) {
    h ^= b;
    h *= 0x100000001b3ULL;
  }
  return h;
}

}  // namespace mapmesh::wire
