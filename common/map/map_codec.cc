#include "common/map/map_codec.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <unordered_set>

namespace mapmesh {
namespace {

static_assert(std::endian::native == std::endian::little, "codec assumes little-endian host");

template <typename T>
void Put(std::vector<std::uint8_t>& out, T v) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.insert(out.end(), b, b + sizeof(T));
}

template <typename T>
T Get(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

constexpr double kMaxAbsMm = 2.1e9;

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
    case MapDecodeError::kOutOfRange: return "out_of_range";
  }
  return "unknown";
}

std::vector<std::uint8_t> EncodeMap(const LandmarkMap& map) {
  std::vector<std::uint8_t> out;
  out.reserve(kMapCodecHeaderBytes + kMapCodecLandmarkBytes * map.size());
  out.push_back('M');
  out.push_back('M');
  out.push_back(kMapCodecVersion);
  out.push_back(0);
  Put<std::uint32_t>(out, static_cast<std::uint32_t>(map.size()));
  for (const Landmark& l : map.landmarks) {
    const double x_mm = std::round(l.mean.x() * 1000.0), y_mm = std::round(l.mean.y() * 1000.0);
    if (!(std::abs(x_mm) < kMaxAbsMm && std::abs(y_mm) < kMaxAbsMm) || !l.cov.allFinite()) {
      return {};
    }
    Put<std::uint32_t>(out, l.id);
    Put<std::int32_t>(out, l.signature);
    Put<std::int32_t>(out, static_cast<std::int32_t>(x_mm));
    Put<std::int32_t>(out, static_cast<std::int32_t>(y_mm));
    Put<float>(out, static_cast<float>(l.cov(0, 0)));
    Put<float>(out, static_cast<float>(0.5 * (l.cov(0, 1) + l.cov(1, 0))));
    Put<float>(out, static_cast<float>(l.cov(1, 1)));
  }
  return out;
}

MapDecodeResult DecodeMap(std::span<const std::uint8_t> payload) {
  MapDecodeResult r;
  auto fail = [&r](MapDecodeError e) {
    r.error = e;
    r.map.landmarks.clear();
    return r;
  };
  if (payload.size() < kMapCodecHeaderBytes) return fail(MapDecodeError::kTruncated);
  const std::uint8_t* p = payload.data();
  if (p[0] != 'M' || p[1] != 'M') return fail(MapDecodeError::kBadMagic);
  if (p[2] != kMapCodecVersion) return fail(MapDecodeError::kUnknownVersion);
  const auto count = Get<std::uint32_t>(p + 4);
  if (count > kMapCodecMaxLandmarks) return fail(MapDecodeError::kOversized);
  const std::size_t expected = kMapCodecHeaderBytes + std::size_t{count} * kMapCodecLandmarkBytes;
  if (payload.size() < expected) return fail(MapDecodeError::kTruncated);
  if (payload.size() > expected) return fail(MapDecodeError::kOversized);

  r.map.landmarks.reserve(count);
  std::unordered_set<std::uint32_t> ids;
  ids.reserve(count);
  p += kMapCodecHeaderBytes;
  for (std::uint32_t i = 0; i < count; ++i, p += kMapCodecLandmarkBytes) {
    Landmark l;
    l.id = Get<std::uint32_t>(p);
    l.signature = Get<std::int32_t>(p + 4);
    l.mean = {Get<std::int32_t>(p + 8) / 1000.0, Get<std::int32_t>(p + 12) / 1000.0};
    const double cxx = Get<float>(p + 16), cxy = Get<float>(p + 20), cyy = Get<float>(p + 24);
    l.cov << cxx, cxy, cxy, cyy;
    if (!l.cov.allFinite()) return fail(MapDecodeError::kNonFinite);
    if (!IsValidCovariance(l.cov)) return fail(MapDecodeError::kBadCovariance);
    if (!ids.insert(l.id).second) return fail(MapDecodeError::kDuplicateId);
    r.map.landmarks.push_back(l);
  }
  return r;
}

}  // namespace mapmesh
