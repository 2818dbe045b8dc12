#include "common/map/map_faults.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>

#include "common/check.h"

namespace mapmesh {
namespace {

constexpr std::array<std::string_view, kPayloadFaultCount> kNames = {
    "truncated",  "oversized",      "count_above_limit", "bad_magic",  "unknown_version",
    "non_finite", "bad_covariance", "duplicate_id",      "bad_header", "out_of_bounds"};

// Byte offsets in the version-2 layout (map_codec.h).
constexpr std::size_t kVersionAt = 2, kFlagsAt = 3, kCountAt = 4, kOriginXAt = 8, kShapeAt = 16;
constexpr std::size_t kRhoInLandmark = 14;

template <typename T>
void Poke(std::vector<std::uint8_t>& bytes, std::size_t at, T v) {
  std::memcpy(bytes.data() + at, &v, sizeof(T));
}

}  // namespace

std::string_view ToString(PayloadFault f) { return kNames[static_cast<std::size_t>(f)]; }

std::optional<PayloadFault> PayloadFaultFromString(std::string_view name) {
  for (std::size_t i = 0; i < kNames.size(); ++i) {
    if (kNames[i] == name) return static_cast<PayloadFault>(i);
  }
  return std::nullopt;
}

MapDecodeError ExpectedDecodeError(PayloadFault f) {
  switch (f) {
    case PayloadFault::kTruncated: return MapDecodeError::kTruncated;
    case PayloadFault::kOversized:
    case PayloadFault::kCountAboveLimit: return MapDecodeError::kOversized;
    case PayloadFault::kBadMagic: return MapDecodeError::kBadMagic;
    case PayloadFault::kUnknownVersion: return MapDecodeError::kUnknownVersion;
    case PayloadFault::kNonFinite: return MapDecodeError::kNonFinite;
    case PayloadFault::kBadCovariance: return MapDecodeError::kBadCovariance;
    case PayloadFault::kDuplicateId: return MapDecodeError::kDuplicateId;
    case PayloadFault::kBadHeader: return MapDecodeError::kBadHeader;
    case PayloadFault::kOutOfBounds: return MapDecodeError::kOutOfBounds;
  }
  return MapDecodeError::kOk;
}

std::vector<std::uint8_t> CorruptPayload(std::span<const std::uint8_t> valid, PayloadFault f) {
  MAPMESH_CHECK(valid.size() >= kMapCodecHeaderBytes + 2 * kMapCodecLandmarkBytes,
                "CorruptPayload needs a payload of at least two landmarks");
  std::vector<std::uint8_t> b(valid.begin(), valid.end());
  const std::size_t first = kMapCodecHeaderBytes, second = first + kMapCodecLandmarkBytes;
  switch (f) {
    case PayloadFault::kTruncated: b.resize(b.size() - kMapCodecLandmarkBytes / 2); break;
    case PayloadFault::kOversized: b.push_back(0); break;
    case PayloadFault::kCountAboveLimit: Poke<std::uint32_t>(b, kCountAt, kMapCodecMaxLandmarks + 1); break;
    case PayloadFault::kBadMagic: b[0] = 'X'; break;
    case PayloadFault::kUnknownVersion: b[kVersionAt] = static_cast<std::uint8_t>(kMapCodecVersion + 1); break;
    case PayloadFault::kNonFinite: Poke<float>(b, kShapeAt, std::numeric_limits<float>::quiet_NaN()); break;
    case PayloadFault::kBadCovariance: Poke<std::int16_t>(b, second + kRhoInLandmark, 32767); break;
    case PayloadFault::kDuplicateId: std::memcpy(b.data() + second, b.data() + first, 4); break;
    case PayloadFault::kBadHeader: b[kFlagsAt] = 0x80; break;
    case PayloadFault::kOutOfBounds: Poke<std::int32_t>(b, kOriginXAt, 2000000000); break;
  }
  return b;
}

LandmarkMap ShuffleCoordinates(const LandmarkMap& map, std::mt19937_64& rng) {
  std::vector<double> xs, ys;
  for (const Landmark& l : map.landmarks) {
    xs.push_back(l.mean.x());
    ys.push_back(l.mean.y());
  }
  std::shuffle(xs.begin(), xs.end(), rng);
  std::shuffle(ys.begin(), ys.end(), rng);
  LandmarkMap out = map;
  for (std::size_t i = 0; i < out.size(); ++i) out.landmarks[i].mean = {xs[i], ys[i]};
  return out;
}

}  // namespace mapmesh
