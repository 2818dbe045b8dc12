#pragma once
// Versioned binary wire codec for landmark maps, with validation on decode.
//
// Version 1 layout (little-endian): magic "MM", u8 version = 1, u8 flags = 0, u32 count,
// then per landmark: u32 id, i32 signature, i32 x_mm, i32 y_mm, f32 cxx, f32 cxy, f32 cyy
// (28 bytes). Positions are rounded to the millimetre.

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "common/map/landmark_map.h"

namespace mapmesh {

inline constexpr std::uint8_t kMapCodecVersion = 1;
inline constexpr std::size_t kMapCodecHeaderBytes = 8;
inline constexpr std::size_t kMapCodecLandmarkBytes = 28;
// Decoding refuses payloads that claim more landmarks than this.
inline constexpr std::uint32_t kMapCodecMaxLandmarks = 100000;

// Why a payload was rejected. kOk means it decoded.
enum class MapDecodeError {
  kOk = 0,
  kTruncated,         // shorter than its header or its count says
  kOversized,         // longer than its count says, or count above the limit
  kBadMagic,
  kUnknownVersion,
  kNonFinite,         // NaN or inf in a mean or covariance
  kBadCovariance,     // not symmetric PSD
  kDuplicateId,
  kOutOfRange,        // a position that does not fit the encoding
};
inline constexpr int kMapDecodeErrorCount = 9;

std::string_view ToString(MapDecodeError e);

// Encodes a map. Fails (returns empty) only if a position is beyond +-2.1e6 m or a value is
// not finite; callers encode maps they produced themselves.
std::vector<std::uint8_t> EncodeMap(const LandmarkMap& map);

struct MapDecodeResult {
  MapDecodeError error = MapDecodeError::kOk;
  LandmarkMap map;  // valid only when error == kOk
  bool ok() const { return error == MapDecodeError::kOk; }
};

// Decodes and validates a payload; never throws, never crashes on malformed input.
MapDecodeResult DecodeMap(std::span<const std::uint8_t> payload);

}  // namespace mapmesh
