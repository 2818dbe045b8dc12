#include "common/map/map_codec.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <unordered_set>

#include "common/map/wire_bytes.h"

namespace mapmesh {
namespace {

using wire::Get;
using wire::Put;

void PutI24(std::vector<std::uint8_t>& out, std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  out.push_back(static_cast<std::uint8_t>(u & 0xff));
  out.push_back(static_cast<std::uint8_t>((u >> 8) & 0xff));
  out.push_back(static_cast<std::uint8_t>((u >> 16) & 0xff));
}

std::int32_t GetI24(const std::uint8_t* p) {
  std::uint32_t u = p[0] | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16);
  if (u & 0x800000u) u |= 0xff000000u;  // sign-extend
  return static_cast<std::int32_t>(u);
}

constexpr std::int32_t kI24Max = (1 << 23) - 1;
constexpr double kSigmaMin = 1e-5;  // m
constexpr double kLogStep = 3e-4;
constexpr std::uint16_t kSigmaCodeMax = 65534;  // 65535 is invalid
constexpr std::int16_t kRhoCodeMax = 32766;
constexpr double kRhoScale = 32767.0;
constexpr double kMaxCoordinateMm = kMapCodecMaxCoordinateM * 1000.0;
static_assert(kMaxCoordinateMm < kI24Max, "a map within the bound must fit the 24-bit offsets");

std::uint16_t SigmaCode(double sigma) {
  const double c = std::round(std::log(std::max(sigma, kSigmaMin) / kSigmaMin) / kLogStep);
  return static_cast<std::uint16_t>(std::clamp(c, 0.0, static_cast<double>(kSigmaCodeMax)));
}

double SigmaOf(std::uint16_t code) { return kSigmaMin * std::exp(code * kLogStep); }

}  // namespace

std::string_view ToString(MapDecodeError e) {
  switch (e) {
    case MapDecodeError::kOk: return "ok";
    case MapDecodeError::kTruncated: return "truncated";
    case MapDecodeError::kOversized: return "oversized";
    case MapDecodeError::kBadMagic: return "bad_magic";
    case MapDecodeError::kUnknownVersion: return "unknown_version";
    case MapDecodeError::kNonFinite: return "non_finite";
    case MapDecodeError::kBadCovariance: return "bad_covariance";
    case MapDecodeError::kDuplicateId: return "duplicate_id";
    case MapDecodeError::kBadHeader: return "bad_header";
    case MapDecodeError::kOutOfBounds: return "out_of_bounds";
  }
  return "unknown";
}

std::vector<std::uint8_t> EncodeMap(const LandmarkMap& map, MapDecodeError* error) {
  auto fail = [error](MapDecodeError e) {
    if (error != nullptr) *error = e;
    return std::vector<std::uint8_t>{};
  };
  if (error != nullptr) *error = MapDecodeError::kOk;
  if (map.size() > kMapCodecMaxLandmarks) return fail(MapDecodeError::kOversized);
  // The origin: the middle of the map's bounding box, to the millimetre. Positions are
  // rounded to the millimetre first, as the decoder sees them.
  double lo_x = 0.0, hi_x = 0.0, lo_y = 0.0, hi_y = 0.0;
  std::unordered_set<std::uint32_t> ids;
  ids.reserve(map.size());
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Landmark& l = map.landmarks[i];
    if (!l.mean.allFinite()) return fail(MapDecodeError::kNonFinite);
    if (!IsValidCovariance(l.cov)) return fail(MapDecodeError::kBadCovariance);
    if (!ids.insert(l.id).second) return fail(MapDecodeError::kDuplicateId);
    const double x = std::round(l.mean.x() * 1000.0), y = std::round(l.mean.y() * 1000.0);
    if (!(std::abs(x) <= kMaxCoordinateMm && std::abs(y) <= kMaxCoordinateMm))
      return fail(MapDecodeError::kOutOfBounds);
    lo_x = i == 0 ? x : std::min(lo_x, x);
    hi_x = i == 0 ? x : std::max(hi_x, x);
    lo_y = i == 0 ? y : std::min(lo_y, y);
    hi_y = i == 0 ? y : std::max(hi_y, y);
  }
  const double ox = std::round(0.5 * (lo_x + hi_x)), oy = std::round(0.5 * (lo_y + hi_y));
  const bool shape_ok = std::isfinite(map.shape_sigma_m) && map.shape_sigma_m > 0 &&
                        map.shape_sigma_m <= std::numeric_limits<float>::max();
  const double shape = shape_ok ? map.shape_sigma_m : 0.0;

  std::vector<std::uint8_t> out;
  out.reserve(kMapCodecHeaderBytes + kMapCodecLandmarkBytes * map.size());
  out.push_back('M');
  out.push_back('M');
  out.push_back(kMapCodecVersion);
  out.push_back(0);
  Put<std::uint32_t>(out, static_cast<std::uint32_t>(map.size()));
  Put<std::int32_t>(out, static_cast<std::int32_t>(ox));
  Put<std::int32_t>(out, static_cast<std::int32_t>(oy));
  Put<float>(out, static_cast<float>(shape));
  for (const Landmark& l : map.landmarks) {
    // Within the bound, |offset| <= 8e6 mm < 2^23 - 1: it always fits.
    const double dx = std::round(l.mean.x() * 1000.0) - ox, dy = std::round(l.mean.y() * 1000.0) - oy;
    const double sx = std::sqrt(std::max(0.0, l.cov(0, 0))), sy = std::sqrt(std::max(0.0, l.cov(1, 1)));
    const double cxy = 0.5 * (l.cov(0, 1) + l.cov(1, 0));
    const double rho = sx > 0 && sy > 0 ? cxy / (sx * sy) : 0.0;
    Put<std::uint32_t>(out, l.id);
    PutI24(out, static_cast<std::int32_t>(dx));
    PutI24(out, static_cast<std::int32_t>(dy));
    Put<std::uint16_t>(out, SigmaCode(sx));
    Put<std::uint16_t>(out, SigmaCode(sy));
    Put<std::int16_t>(out, static_cast<std::int16_t>(std::clamp(std::round(rho * kRhoScale), -double{kRhoCodeMax},
                                                                double{kRhoCodeMax})));
  }
  return out;
}

std::optional<std::uint32_t> MapPayloadCount(std::span<const std::uint8_t> payload) {
  if (payload.size() < kMapCodecHeaderBytes) return std::nullopt;
  const std::uint8_t* p = payload.data();
  if (p[0] != 'M' || p[1] != 'M' || p[2] != kMapCodecVersion) return std::nullopt;
  return Get<std::uint32_t>(p + 4);
}

MapDecodeResult DecodeMap(std::span<const std::uint8_t> payload) {
  MapDecodeResult r;
  auto fail = [&r](MapDecodeError e) {
    r.error = e;
    r.map = LandmarkMap{};
    return r;
  };
  if (payload.size() < 4) return fail(MapDecodeError::kTruncated);
  const std::uint8_t* p = payload.data();
  if (p[0] != 'M' || p[1] != 'M') return fail(MapDecodeError::kBadMagic);
  if (p[2] != kMapCodecVersion) return fail(MapDecodeError::kUnknownVersion);
  if (payload.size() < kMapCodecHeaderBytes) return fail(MapDecodeError::kTruncated);
  if (p[3] != 0) return fail(MapDecodeError::kBadHeader);
  const auto count = Get<std::uint32_t>(p + 4);
  if (count > kMapCodecMaxLandmarks) return fail(MapDecodeError::kOversized);
  const std::size_t expected = kMapCodecHeaderBytes + std::size_t{count} * kMapCodecLandmarkBytes;
  if (payload.size() < expected) return fail(MapDecodeError::kTruncated);
  if (payload.size() > expected) return fail(MapDecodeError::kOversized);
  const double ox = Get<std::int32_t>(p + 8), oy = Get<std::int32_t>(p + 12);
  const double shape = Get<float>(p + 16);
  if (!std::isfinite(shape)) return fail(MapDecodeError::kNonFinite);
  if (shape < 0) return fail(MapDecodeError::kBadHeader);
  if (std::abs(ox) > kMaxCoordinateMm || std::abs(oy) > kMaxCoordinateMm) return fail(MapDecodeError::kOutOfBounds);
  r.map.shape_sigma_m = shape;

  r.map.landmarks.reserve(count);
  std::unordered_set<std::uint32_t> ids;
  ids.reserve(count);
  p += kMapCodecHeaderBytes;
  for (std::uint32_t i = 0; i < count; ++i, p += kMapCodecLandmarkBytes) {
    Landmark l;
    l.id = Get<std::uint32_t>(p);
    const double x_mm = ox + GetI24(p + 4), y_mm = oy + GetI24(p + 7);
    if (std::abs(x_mm) > kMaxCoordinateMm || std::abs(y_mm) > kMaxCoordinateMm)
      return fail(MapDecodeError::kOutOfBounds);
    l.mean = {x_mm / 1000.0, y_mm / 1000.0};
    const auto cx = Get<std::uint16_t>(p + 10), cy = Get<std::uint16_t>(p + 12);
    const auto cr = Get<std::int16_t>(p + 14);
    if (cx > kSigmaCodeMax || cy > kSigmaCodeMax) return fail(MapDecodeError::kNonFinite);
    if (cr > kRhoCodeMax || cr < -kRhoCodeMax) return fail(MapDecodeError::kBadCovariance);
    const double sx = SigmaOf(cx), sy = SigmaOf(cy), rho = cr / kRhoScale;
    l.cov << sx * sx, rho * sx * sy, rho * sx * sy, sy * sy;
    if (!ids.insert(l.id).second) return fail(MapDecodeError::kDuplicateId);
    r.map.landmarks.push_back(l);
  }
  return r;
}

}  // namespace mapmesh
