#pragma once
// Compact, versioned binary wire codec for landmark maps, with validation on decode.
//
// Version 2 layout (little-endian). Header, 20 bytes: magic "MM", u8 version = 2, u8 flags = 0,
// u32 count, i32 origin_x_mm, i32 origin_y_mm, f32 shape_sigma_m (LandmarkMap::shape_sigma_m).
// Then 16 bytes per landmark:
//   u32 id;
//   i24 dx_mm, i24 dy_mm     position relative to the origin, to the millimetre (+-8.3 km);
//   u16 log_sx, u16 log_sy   standard deviations on a log scale: sigma = 1e-5 m * exp(code *
//                            3e-4), 10 um to 3.4 km, 0.015 % steps (65535 is invalid);
//   i16 rho                  correlation * 32767, |code| <= 32766 (a positive-definite matrix).
// The covariance is rebuilt as [sx^2, rho sx sy; rho sx sy, sy^2]: its relative error is below
// 0.1 %. Signatures are not sent: robots share landmarks by geometry only.

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "common/map/landmark_map.h"

namespace mapmesh {

inline constexpr std::uint8_t kMapCodecVersion = 2;
inline constexpr std::size_t kMapCodecHeaderBytes = 20;
inline constexpr std::size_t kMapCodecLandmarkBytes = 16;
// Decoding refuses payloads that claim more landmarks than this.
inline constexpr std::uint32_t kMapCodecMaxLandmarks = 100000;

// Why a payload was rejected. kOk means it decoded.
enum class MapDecodeError {
  kOk = 0,
  kTruncated,      // shorter than its header or its count says
  kOversized,      // longer than its count says, or count above the limit
  kBadMagic,
  kUnknownVersion,
  kNonFinite,      // NaN or inf (the shape precision, or an invalid standard-deviation code)
  kBadCovariance,  // not positive definite (a correlation code out of range)
  kDuplicateId,
  kBadHeader,      // unknown flags, or a negative shape precision
};
inline constexpr int kMapDecodeErrorCount = 9;

std::string_view ToString(MapDecodeError e);

// Encodes a map. Standard deviations outside the code's range are clamped to it, and
// correlations to +-0.99997. Fails (returns empty) when a mean or covariance is not finite,
// a covariance is not symmetric PSD, or the map spans more than the position encoding allows.
std::vector<std::uint8_t> EncodeMap(const LandmarkMap& map);

struct MapDecodeResult {
  MapDecodeError error = MapDecodeError::kOk;
  LandmarkMap map;  // valid only when error == kOk
  bool ok() const { return error == MapDecodeError::kOk; }
};

// Decodes and validates a payload; never throws, never crashes on malformed input.
MapDecodeResult DecodeMap(std::span<const std::uint8_t> payload);

}  // namespace mapmesh
