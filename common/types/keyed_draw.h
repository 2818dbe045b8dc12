#pragma once
// Draws that are functions of a key, not of a generator's state: the same key gives the same
// draw whatever else was drawn before, so a lockstep run's radio (the feeder's links, an
// agent's link latencies) is the same run again and does not depend on the order in which
// pairs or messages are met. Pure: no global state.

#include <cmath>
#include <cstdint>
#include <initializer_list>

namespace mapmesh {

// splitmix64's output function: a bijective mix of 64 bits.
inline std::uint64_t Mix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// The key of one draw: the seed, then each part mixed in turn (a stream number naming what is
// drawn, the pair, an index such as a period or a stamp in milliseconds).
inline std::uint64_t DrawKey(std::uint64_t seed, std::initializer_list<std::uint64_t> parts) {
  std::uint64_t k = Mix64(seed);
  for (std::uint64_t part : parts) k = Mix64(k ^ part);
  return k;
}

// A uniform draw in [0, 1) from a key (its 53 high bits after one more mix).
inline double UniformDraw(std::uint64_t key) { return static_cast<double>(Mix64(key) >> 11) * 0x1.0p-53; }

// A standard normal draw from a key (Box-Muller on two mixes of it).
inline double NormalDraw(std::uint64_t key) {
  const std::uint64_t h1 = Mix64(key), h2 = Mix64(h1);
  const double u1 = (static_cast<double>(h1 >> 11) + 1.0) * 0x1.0p-53;  // (0, 1]
  const double u2 = static_cast<double>(h2 >> 11) * 0x1.0p-53;          // [0, 1)
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

}  // namespace mapmesh
