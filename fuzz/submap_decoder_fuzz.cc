// libFuzzer target for the submap wire codec (common/map/submap_codec.h): DecodeSubmap on
// arbitrary bytes, checking the codec's contract: a refused payload leaves an empty submap; a
// decoded one has distinct ids, sizes that agree, finite values within the bound, stamps in
// order and a positive-definite covariance; it re-encodes to the very bytes it came from (a
// relayed submap is the one its robot sent); and SubmapBook takes it once, counts the same
// bytes again as a duplicate and a change of one byte under its identity as a conflict.

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdint>
#include <span>
#include <unordered_set>
#include <vector>

#include "common/map/submap_book.h"
#include "common/map/submap_codec.h"
#include "fuzz/fuzz_check.h"

namespace mapmesh {
namespace {

void CheckDecodedSubmap(const WireSubmap& s) {
  const auto n = static_cast<Eigen::Index>(s.keys.size());
  MAPMESH_FUZZ_CHECK(s.keys.size() <= kSubmapCodecMaxLandmarks);
  MAPMESH_FUZZ_CHECK(s.x.size() == 3 + 2 * n);
  MAPMESH_FUZZ_CHECK(s.l.rows() == 3 + 2 * n && s.l.cols() == 3 + 2 * n);
  MAPMESH_FUZZ_CHECK(std::isfinite(s.opened_s) && std::isfinite(s.closed_s) && s.opened_s <= s.closed_s);
  MAPMESH_FUZZ_CHECK(s.x.allFinite() && s.l.allFinite());
  std::unordered_set<std::uint32_t> ids(s.keys.begin(), s.keys.end());
  MAPMESH_FUZZ_CHECK(ids.size() == s.keys.size());
  for (Eigen::Index i = 0; i < s.x.size(); ++i) {
    if (i != 2) MAPMESH_FUZZ_CHECK(std::abs(s.x(i)) <= kSubmapCodecMaxCoordinateM);
  }
  for (Eigen::Index r = 0; r < s.l.rows(); ++r) {
    MAPMESH_FUZZ_CHECK(s.l(r, r) > 0.0);
    for (Eigen::Index c = r + 1; c < s.l.cols(); ++c) MAPMESH_FUZZ_CHECK(s.l(r, c) == 0.0);
  }
}

void FuzzOne(std::span<const std::uint8_t> payload) {
  const SubmapDecodeResult r = DecodeSubmap(payload);
  MAPMESH_FUZZ_CHECK(ToString(r.error) != "unknown");
  if (!r.ok()) {
    MAPMESH_FUZZ_CHECK(r.submap.keys.empty() && r.submap.x.size() == 3);
    return;
  }
  CheckDecodedSubmap(r.submap);
  MAPMESH_FUZZ_CHECK(payload.size() == SubmapPayloadBytes(static_cast<std::uint32_t>(r.submap.keys.size())));
  // The encoder accepts what the decoder accepted, and writes the same bytes.
  SubmapDecodeError error = SubmapDecodeError::kTruncated;
  const std::vector<std::uint8_t> again = EncodeSubmap(r.submap, &error);
  MAPMESH_FUZZ_CHECK(error == SubmapDecodeError::kOk);
  MAPMESH_FUZZ_CHECK(std::equal(again.begin(), again.end(), payload.begin(), payload.end()));
  // Identity: once; the same bytes a duplicate; other bytes under the same identity a conflict.
  SubmapBook book;
  MAPMESH_FUZZ_CHECK(book.Add(r.submap, payload) == SubmapBook::Offer::kNew);
  MAPMESH_FUZZ_CHECK(book.Add(r.submap, payload) == SubmapBook::Offer::kDuplicate);
  std::vector<std::uint8_t> other(payload.begin(), payload.end());
  other.back() ^= 0x01;
  MAPMESH_FUZZ_CHECK(book.Add(r.submap, other) == SubmapBook::Offer::kConflict);
  MAPMESH_FUZZ_CHECK(book.size() == 1 && book.duplicates() == 1 && book.conflicts() == 1);
}

}  // namespace
}  // namespace mapmesh

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  mapmesh::FuzzOne(std::span<const std::uint8_t>(data, size));
  return 0;
}
