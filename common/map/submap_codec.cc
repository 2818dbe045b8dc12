#include "common/map/submap_codec.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>

#include "common/map/wire_bytes.h"

namespace mapmesh {
namespace {

using wire::Get;
using wire::Put;

constexpr char kMagic[2] = {'M', 'S'};

std::size_t StateSize(std::uint32_t landmarks) { return 3 + 2 * static_cast<std::size_t>(landmarks); }

// Whether every landmark mean and the end position lie within the bound.
bool InBounds(const Eigen::VectorXd& x) {
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    if (i == 2) continue;  // the end heading
    if (std::abs(x(i)) > kSubmapCodecMaxCoordinateM) return false;
  }
  return true;
}

bool DistinctKeys(std::vector<std::uint32_t> keys) {
  std::sort(keys.begin(), keys.end());
  return std::adjacent_find(keys.begin(), keys.end()) == keys.end();
}

}  // namespace

std::string_view ToString(SubmapDecodeError e) {
  switch (e) {
    case SubmapDecodeError::kOk: return "ok";
    case SubmapDecodeError::kTruncated: return "truncated";
    case SubmapDecodeError::kOversized: return "oversized";
    case SubmapDecodeError::kBadMagic: return "bad_magic";
    case SubmapDecodeError::kUnknownVersion: return "unknown_version";
    case SubmapDecodeError::kBadHeader: return "bad_header";
    case SubmapDecodeError::kNonFinite: return "non_finite";
    case SubmapDecodeError::kBadCovariance: return "bad_covariance";
    case SubmapDecodeError::kDuplicateId: return "duplicate_id";
    case SubmapDecodeError::kOutOfBounds: return "out_of_bounds";
  }
  return "unknown";
}

namespace {
// A diagonal entry of L: positive and a normal f32 (issue R3: a denormal one, below 1.2e-38, was
// taken; its covariance is singular in any arithmetic that follows).
bool PositiveNormal(float v) { return v > 0.0f && std::isnormal(v); }
}  // namespace

bool WireSubmap::SetCovariance(const Eigen::MatrixXd& p) {
  if (p.rows() != p.cols() || !p.allFinite() || (p - p.transpose()).cwiseAbs().maxCoeff() > 1e-9 * p.norm()) {
    return false;
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(0.5 * (p + p.transpose()));
  if (llt.info() != Eigen::Success) return false;
  Eigen::MatrixXd f = llt.matrixL();
  // As the wire holds it; a diagonal entry that rounds to 0 in f32 would not be accepted.
  f = f.cast<float>().cast<double>();
  if (!f.allFinite()) return false;
  for (Eigen::Index r = 0; r < f.rows(); ++r) {
    if (!PositiveNormal(static_cast<float>(f(r, r)))) return false;
  }
  l = std::move(f);
  return true;
}

std::size_t SubmapPayloadBytes(std::uint32_t landmarks) {
  const std::size_t m = StateSize(landmarks);
  return kSubmapCodecHeaderBytes + 4 * static_cast<std::size_t>(landmarks) + 8 * m + 4 * (m * (m + 1) / 2);
}

std::uint32_t SubmapLandmarksWithin(std::size_t bytes) {
  if (SubmapPayloadBytes(0) > bytes) return 0;
  std::uint32_t n = 0;
  while (n < kSubmapCodecMaxLandmarks && SubmapPayloadBytes(n + 1) <= bytes) ++n;
  return n;
}

std::vector<std::uint8_t> EncodeSubmap(const WireSubmap& s, SubmapDecodeError* error) {
  auto fail = [error](SubmapDecodeError e) {
    if (error != nullptr) *error = e;
    return std::vector<std::uint8_t>{};
  };
  if (s.keys.size() > kSubmapCodecMaxLandmarks) return fail(SubmapDecodeError::kOversized);
  const auto n = static_cast<std::uint32_t>(s.keys.size());
  const auto m = static_cast<Eigen::Index>(StateSize(n));
  if (s.x.size() != m || s.l.rows() != m || s.l.cols() != m) return fail(SubmapDecodeError::kTruncated);
  if (!std::isfinite(s.opened_s) || !std::isfinite(s.closed_s) || s.closed_s < s.opened_s) {
    return fail(SubmapDecodeError::kBadHeader);
  }
  if (!s.x.allFinite() || !s.l.allFinite()) return fail(SubmapDecodeError::kNonFinite);
  if (!DistinctKeys(s.keys)) return fail(SubmapDecodeError::kDuplicateId);
  if (!InBounds(s.x)) return fail(SubmapDecodeError::kOutOfBounds);
  for (Eigen::Index r = 0; r < m; ++r) {
    if (!PositiveNormal(static_cast<float>(s.l(r, r)))) return fail(SubmapDecodeError::kBadCovariance);
    for (Eigen::Index c = 0; c <= r; ++c) {
      if (!std::isfinite(static_cast<float>(s.l(r, c)))) return fail(SubmapDecodeError::kNonFinite);
    }
    for (Eigen::Index c = r + 1; c < m; ++c) {
      if (s.l(r, c) != 0.0) return fail(SubmapDecodeError::kBadCovariance);  // not lower triangular
    }
  }
  std::vector<std::uint8_t> out;
  out.reserve(SubmapPayloadBytes(n));
  out.push_back(static_cast<std::uint8_t>(kMagic[0]));
  out.push_back(static_cast<std::uint8_t>(kMagic[1]));
  out.push_back(kSubmapCodecVersion);
  out.push_back(0);  // flags
  Put<std::uint32_t>(out, s.id.robot);
  Put<std::uint32_t>(out, s.id.incarnation);
  Put<std::uint32_t>(out, s.id.index);
  Put<double>(out, s.opened_s);
  Put<double>(out, s.closed_s);
  Put<std::uint32_t>(out, n);
  for (std::uint32_t k : s.keys) Put<std::uint32_t>(out, k);
  for (Eigen::Index i = 0; i < m; ++i) Put<double>(out, s.x(i));
  for (Eigen::Index r = 0; r < m; ++r) {
    for (Eigen::Index c = 0; c <= r; ++c) Put<float>(out, static_cast<float>(s.l(r, c)));
  }
  if (error != nullptr) *error = SubmapDecodeError::kOk;
  return out;
}

SubmapDecodeResult DecodeSubmap(std::span<const std::uint8_t> payload) {
  SubmapDecodeResult out;
  auto fail = [&out](SubmapDecodeError e) {
    out.error = e;
    out.submap = WireSubmap{};
    return out;
  };
  if (payload.size() < kSubmapCodecHeaderBytes) return fail(SubmapDecodeError::kTruncated);
  const std::uint8_t* p = payload.data();
  if (p[0] != kMagic[0] || p[1] != kMagic[1]) return fail(SubmapDecodeError::kBadMagic);
  if (p[2] != kSubmapCodecVersion) return fail(SubmapDecodeError::kUnknownVersion);
  if (p[3] != 0) return fail(SubmapDecodeError::kBadHeader);
  WireSubmap& s = out.submap;
  s.id = {Get<std::uint32_t>(p + 4), Get<std::uint32_t>(p + 8), Get<std::uint32_t>(p + 12)};
  s.opened_s = Get<double>(p + 16);
  s.closed_s = Get<double>(p + 24);
  const auto n = Get<std::uint32_t>(p + 32);
  if (n > kSubmapCodecMaxLandmarks) return fail(SubmapDecodeError::kOversized);
  const std::size_t want = SubmapPayloadBytes(n);
  if (payload.size() < want) return fail(SubmapDecodeError::kTruncated);
  if (payload.size() > want) return fail(SubmapDecodeError::kOversized);
  if (!std::isfinite(s.opened_s) || !std::isfinite(s.closed_s) || s.closed_s < s.opened_s) {
    return fail(SubmapDecodeError::kBadHeader);
  }
  const auto m = static_cast<Eigen::Index>(StateSize(n));
  std::size_t at = kSubmapCodecHeaderBytes;
  s.keys.resize(n);
  for (std::uint32_t i = 0; i < n; ++i, at += 4) s.keys[i] = Get<std::uint32_t>(p + at);
  s.x.resize(m);
  for (Eigen::Index i = 0; i < m; ++i, at += 8) s.x(i) = Get<double>(p + at);
  s.l = Eigen::MatrixXd::Zero(m, m);
  for (Eigen::Index r = 0; r < m; ++r) {
    for (Eigen::Index c = 0; c <= r; ++c, at += 4) s.l(r, c) = Get<float>(p + at);
  }
  if (!s.x.allFinite() || !s.l.allFinite()) return fail(SubmapDecodeError::kNonFinite);
  if (!DistinctKeys(s.keys)) return fail(SubmapDecodeError::kDuplicateId);
  if (!InBounds(s.x)) return fail(SubmapDecodeError::kOutOfBounds);
  for (Eigen::Index r = 0; r < s.l.rows(); ++r) {
    if (!PositiveNormal(static_cast<float>(s.l(r, r)))) return fail(SubmapDecodeError::kBadCovariance);
  }
  return out;
}

}  // namespace mapmesh
