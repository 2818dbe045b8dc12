#pragma once
// Little-endian fixed-size values in a byte buffer, for the wire codecs (map_codec, submap_codec).

#include <bit>
#include <cstdint>
#include <cstring>
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

}  // namespace mapmesh::wire
