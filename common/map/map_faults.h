#pragma once
// Deliberately wrong maps, for fault-injection experiments and tests (mapmesh-inject): a valid
// payload corrupted so that DecodeMap must refuse it for one named reason, and a well-formed
// map whose geometry is wrong (its coordinates shuffled between landmarks).

#include <cstdint>
#include <optional>
#include <random>
#include <span>
#include <string_view>
#include <vector>

#include "common/map/landmark_map.h"
#include "common/map/map_codec.h"

namespace mapmesh {

// One way to break a valid payload; each maps to the MapDecodeError that must reject it.
enum class PayloadFault {
  kTruncated,        // the last landmark cut short
  kOversized,        // one byte more than the count says
  kCountAboveLimit,  // a landmark count above kMapCodecMaxLandmarks
  kBadMagic,
  kUnknownVersion,
  kNonFinite,      // a NaN shape precision
  kBadCovariance,  // a correlation code of exactly +-1 on one landmark
  kDuplicateId,    // the second landmark takes the first one's id
  kBadHeader,      // unknown flags
  kOutOfBounds,    // the map's origin 2000 km away (beyond kMapCodecMaxCoordinateM)
};
inline constexpr int kPayloadFaultCount = 10;

std::string_view ToString(PayloadFault f);
std::optional<PayloadFault> PayloadFaultFromString(std::string_view name);
MapDecodeError ExpectedDecodeError(PayloadFault f);

// Corrupts `valid` (an EncodeMap payload of at least two landmarks) with fault f.
std::vector<std::uint8_t> CorruptPayload(std::span<const std::uint8_t> valid, PayloadFault f);

// The same ids and covariances, each landmark's x and y taken from other landmarks (two
// independent random permutations): well-formed, plausible, and geometrically wrong.
LandmarkMap ShuffleCoordinates(const LandmarkMap& map, std::mt19937_64& rng);

}  // namespace mapmesh
