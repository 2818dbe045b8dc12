// libFuzzer target for the map wire codec (common/map/map_codec.h): DecodeMap and
// MapPayloadCount on arbitrary bytes, checking the codec's contract that the encoder and the
// decoder accept exactly the same maps. The same bytes, read as a raw map (44 bytes per
// landmark: u32 id, f64 x, y, cov xx, xy, yy; then an f64 shape precision), also check the
// encoder's side: it accepts exactly the valid maps, and what it writes decodes to them.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <unordered_set>
#include <vector>

#include "common/map/landmark_map.h"
#include "common/map/map_codec.h"
#include "fuzz/fuzz_check.h"

namespace mapmesh {
namespace {

// a and b agree to 1e-9 relative to scale.
bool Near(double a, double b, double scale) { return std::abs(a - b) <= 1e-9 * scale; }

// Two maps hold the same landmarks (ids, exact means, covariances to 1e-9 relative) and
// the same shape precision.
bool SameMap(const LandmarkMap& a, const LandmarkMap& b) {
  if (a.size() != b.size() || a.shape_sigma_m != b.shape_sigma_m) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Landmark& x = a.landmarks[i];
    const Landmark& y = b.landmarks[i];
    if (x.id != y.id || x.mean != y.mean) return false;
    const double scale = std::max({std::abs(x.cov(0, 0)), std::abs(x.cov(1, 1)), 1e-300});
    for (int k = 0; k < 4; ++k) {
      if (!Near(x.cov(k / 2, k % 2), y.cov(k / 2, k % 2), scale)) return false;
    }
  }
  return true;
}

// What every decoded map satisfies: unique ids, finite means within the codec's bound, valid
// covariances, a finite non-negative shape precision, at most kMapCodecMaxLandmarks.
void CheckDecodedMap(const LandmarkMap& map) {
  MAPMESH_FUZZ_CHECK(map.size() <= kMapCodecMaxLandmarks);
  MAPMESH_FUZZ_CHECK(std::isfinite(map.shape_sigma_m) && map.shape_sigma_m >= 0);
  std::unordered_set<std::uint32_t> ids;
  for (const Landmark& l : map.landmarks) {
    MAPMESH_FUZZ_CHECK(ids.insert(l.id).second);
    MAPMESH_FUZZ_CHECK(l.mean.allFinite());
    MAPMESH_FUZZ_CHECK(std::abs(l.mean.x()) <= kMapCodecMaxCoordinateM);
    MAPMESH_FUZZ_CHECK(std::abs(l.mean.y()) <= kMapCodecMaxCoordinateM);
    MAPMESH_FUZZ_CHECK(IsValidCovariance(l.cov));
    MAPMESH_FUZZ_CHECK(l.signature == -1);  // not sent
  }
}

// The header's count, read as MapPayloadCount documents it.
std::optional<std::uint32_t> HeaderCount(std::span<const std::uint8_t> payload) {
  if (payload.size() < kMapCodecHeaderBytes || payload[0] != 'M' || payload[1] != 'M' ||
      payload[2] != kMapCodecVersion) {
    return std::nullopt;
  }
  std::uint32_t count;
  std::memcpy(&count, payload.data() + 4, sizeof count);
  return count;
}

void FuzzOne(std::span<const std::uint8_t> payload) {
  const std::optional<std::uint32_t> count = MapPayloadCount(payload);
  MAPMESH_FUZZ_CHECK(count == HeaderCount(payload));

  const MapDecodeResult r = DecodeMap(payload);
  MAPMESH_FUZZ_CHECK(ToString(r.error) != "unknown");
  if (!r.ok()) {
    MAPMESH_FUZZ_CHECK(r.map.empty() && r.map.shape_sigma_m == 0.0);
    return;
  }
  CheckDecodedMap(r.map);
  MAPMESH_FUZZ_CHECK(count.has_value() && *count == r.map.size());

  // The encoder accepts what the decoder accepted, and its payload decodes to the same map.
  MapDecodeError error = MapDecodeError::kTruncated;
  const std::vector<std::uint8_t> again = EncodeMap(r.map, &error);
  MAPMESH_FUZZ_CHECK(error == MapDecodeError::kOk);
  MAPMESH_FUZZ_CHECK(again.size() == kMapCodecHeaderBytes + kMapCodecLandmarkBytes * r.map.size());
  MAPMESH_FUZZ_CHECK(MapPayloadCount(again) == std::optional<std::uint32_t>(r.map.size()));
  const MapDecodeResult r2 = DecodeMap(again);
  MAPMESH_FUZZ_CHECK(r2.ok());
  MAPMESH_FUZZ_CHECK(SameMap(r.map, r2.map));
  // A decoded map is a fixed point: encoding it again gives the same bytes.
  MAPMESH_FUZZ_CHECK(EncodeMap(r2.map) == again);
}

// The map that 44-byte records of raw bytes spell (at most 256), any values at all.
LandmarkMap RawMap(std::span<const std::uint8_t> bytes) {
  constexpr std::size_t kRecord = 4 + 5 * sizeof(double);
  LandmarkMap map;
  const std::size_t n = std::min<std::size_t>(bytes.size() / kRecord, 256);
  const std::uint8_t* p = bytes.data();
  for (std::size_t i = 0; i < n; ++i, p += kRecord) {
    Landmark l;
    double v[5];
    std::memcpy(&l.id, p, 4);
    std::memcpy(v, p + 4, sizeof v);
    l.mean = {v[0], v[1]};
    l.cov << v[2], v[3], v[3], v[4];
    map.landmarks.push_back(l);
  }
  if (bytes.size() - n * kRecord >= sizeof(double)) std::memcpy(&map.shape_sigma_m, p, sizeof(double));
  return map;
}

// What EncodeMap documents that it accepts: finite means within the bound (to the millimetre),
// valid covariances, unique ids.
bool Encodable(const LandmarkMap& map) {
  std::unordered_set<std::uint32_t> ids;
  for (const Landmark& l : map.landmarks) {
    if (!l.mean.allFinite() || !IsValidCovariance(l.cov) || !ids.insert(l.id).second) return false;
    const double bound_mm = kMapCodecMaxCoordinateM * 1000.0;
    if (!(std::abs(std::round(l.mean.x() * 1000.0)) <= bound_mm &&
          std::abs(std::round(l.mean.y() * 1000.0)) <= bound_mm)) {
      return false;
    }
  }
  return true;
}

// The encoder's side of the contract on an arbitrary map: it encodes exactly the encodable
// maps, and the payload decodes to the map quantized as documented.
void FuzzEncoder(const LandmarkMap& map) {
  MapDecodeError error = MapDecodeError::kOk;
  const std::vector<std::uint8_t> payload = EncodeMap(map, &error);
  MAPMESH_FUZZ_CHECK((error == MapDecodeError::kOk) == Encodable(map));
  MAPMESH_FUZZ_CHECK((error == MapDecodeError::kOk) == !payload.empty());
  if (error != MapDecodeError::kOk) return;
  const MapDecodeResult r = DecodeMap(payload);
  MAPMESH_FUZZ_CHECK(r.ok());
  CheckDecodedMap(r.map);
  MAPMESH_FUZZ_CHECK(r.map.size() == map.size());
  const double s = map.shape_sigma_m;
  const bool shape_sent = std::isfinite(s) && s > 0 && s <= std::numeric_limits<float>::max();
  MAPMESH_FUZZ_CHECK(r.map.shape_sigma_m == (shape_sent ? static_cast<double>(static_cast<float>(s)) : 0.0));
  const double sigma_lo = 1e-5, sigma_hi = 1e-5 * std::exp(65534 * 3e-4);  // the code's range
  for (std::size_t i = 0; i < map.size(); ++i) {
    const Landmark& in = map.landmarks[i];
    const Landmark& out = r.map.landmarks[i];
    MAPMESH_FUZZ_CHECK(out.id == in.id);
    MAPMESH_FUZZ_CHECK(out.mean.x() == std::round(in.mean.x() * 1000.0) / 1000.0);
    MAPMESH_FUZZ_CHECK(out.mean.y() == std::round(in.mean.y() * 1000.0) / 1000.0);
    double sigma_in[2], sigma_out[2];
    for (int a = 0; a < 2; ++a) {
      sigma_in[a] = std::sqrt(std::max(0.0, in.cov(a, a)));
      sigma_out[a] = std::sqrt(out.cov(a, a));
      const double expected = std::clamp(sigma_in[a], sigma_lo, sigma_hi);
      MAPMESH_FUZZ_CHECK(std::abs(sigma_out[a] / expected - 1.0) <= 2e-4);
    }
    // The correlation to 1/32767 (clamped to +-32766/32767).
    const double rho_in = sigma_in[0] > 0 && sigma_in[1] > 0 ? in.cov(0, 1) / (sigma_in[0] * sigma_in[1]) : 0.0;
    const double rho_out = out.cov(0, 1) / (sigma_out[0] * sigma_out[1]);
    MAPMESH_FUZZ_CHECK(std::abs(rho_out - std::clamp(rho_in, -32766.0 / 32767, 32766.0 / 32767)) <= 1.01 / 32767);
  }
}

}  // namespace
}  // namespace mapmesh

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  mapmesh::FuzzOne(bytes);
  mapmesh::FuzzEncoder(mapmesh::RawMap(bytes));
  return 0;
}
