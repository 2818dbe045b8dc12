#pragma once
// Compact, versioned binary wire codec for landmark maps, with validation on decode.
//
// Version 2 layout (little-endian). Header, 20 bytes: magic "MM", u8 version = 2, u8 flags = 0,
// u32 count, i32 origin_x_mm, i32 origin_y_mm, f32 shape_sigma_m (LandmarkMap::shape_sigma_m).
// Every coordinate, the origin included, lies within +-kMapCodecMaxCoordinateM of the frame's
// origin, so that any map of the format spans at most 16 km and every offset fits in 24 bits.
// Then 16 bytes per landmark:
//   u32 id;
//   i24 dx_mm, i24 dy_mm     position relative to the origin, to the millimetre (+-8.3 km);
//   u16 log_sx, u16 log_sy   standard deviations on a log scale: sigma = 1e-5 m * exp(code *
//                            3e-4), 10 um to 3.4 km, 0.015 % steps (65535 is invalid);
//   i16 rho                  correlation * 32767, |code| <= 32766 (a positive-definite matrix).
// The covariance is rebuilt as [sx^2, rho sx sy; rho sx sy, sy^2]: its relative error is below
// 0.1 %. Signatures are not sent: robots share landmarks by geometry only.
//
// The encoder and the decoder accept exactly the same maps: a payload decodes if and only if
// it is the encoding of a map the encoder accepts (and re-encoding a decoded map gives a payload
// that decodes to the same map), so a receiver never holds a map it could not pass on.

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "common/map/landmark_map.h"

namespace mapmesh {

inline constexpr std::uint8_t kMapCodecVersion = 2;
inline constexpr std::size_t kMapCodecHeaderBytes = 20;
inline constexpr std::size_t kMapCodecLandmarkBytes = 16;
// Neither side accepts a map of more landmarks than this ...
inline constexpr std::uint32_t kMapCodecMaxLandmarks = 100000;
// ... nor a coordinate farther than this from the map frame's origin (m).
inline constexpr double kMapCodecMaxCoordinateM = 8000.0;

// Why a payload was rejected. kOk means it decoded.
enum class MapDecodeError {
  kOk = 0,
  kTruncated,  // shorter than its header or its count says
  kOversized,  // longer than its count says, or count above the limit
  kBadMagic,
  kUnknownVersion,
  kNonFinite,      // NaN or inf (the shape precision, or an invalid standard-deviation code)
  kBadCovariance,  // not positive definite (a correlation code out of range)
  kDuplicateId,
  kBadHeader,    // unknown flags, or a negative shape precision
  kOutOfBounds,  // the origin or a landmark beyond kMapCodecMaxCoordinateM
};
inline constexpr int kMapDecodeErrorCount = 10;

std::string_view ToString(MapDecodeError e);

// Encodes a map. Standard deviations outside the code's range are clamped to it, correlations
// to +-0.99997, and a shape precision that is not a finite float becomes 0 (unknown). Fails
// (returns empty, with the reason in *error when given) when the map has more than
// kMapCodecMaxLandmarks landmarks, a mean or covariance is not finite, a covariance is not
// symmetric PSD, two landmarks share an id, or a coordinate lies beyond kMapCodecMaxCoordinateM.
std::vector<std::uint8_t> EncodeMap(const LandmarkMap& map, MapDecodeError* error = nullptr);

struct MapDecodeResult {
  MapDecodeError error = MapDecodeError::kOk;
  LandmarkMap map;  // valid only when error == kOk
  bool ok() const { return error == MapDecodeError::kOk; }
};

// Decodes and validates a payload; never throws, never crashes on malformed input.
MapDecodeResult DecodeMap(std::span<const std::uint8_t> payload);

// The landmark count a payload's header claims, without decoding it (nullopt when the payload
// is too short or not of this codec), so that a receiver can refuse a map too large for it
// before spending work on it.
std::optional<std::uint32_t> MapPayloadCount(std::span<const std::uint8_t> payload);

}  // namespace mapmesh
