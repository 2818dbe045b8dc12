#include "common/map/map_codec.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <cstring>
#include <limits>
#include <random>

namespace mapmesh {
namespace {

LandmarkMap RandomMap(int n, std::uint64_t seed, double extent_m = 500.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-extent_m, extent_m), ls(std::log(1e-3), std::log(100.0)), ur(-0.999, 0.999);
  LandmarkMap m;
  m.shape_sigma_m = 0.25;
  for (int i = 0; i < n; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(3 * i + 1);
    l.mean = {u(rng) + 1234.5, u(rng) - 987.6};
    const double sx = std::exp(ls(rng)), sy = std::exp(ls(rng)), rho = ur(rng);
    l.cov << sx * sx, rho * sx * sy, rho * sx * sy, sy * sy;
    m.landmarks.push_back(l);
  }
  return m;
}

TEST(MapCodec, SixteenBytesPerLandmarkMillimetresAndCovariancesWithinOnePercent) {
  const LandmarkMap m = RandomMap(2000, 1);
  const auto bytes = EncodeMap(m);
  EXPECT_EQ(kMapCodecLandmarkBytes, 16u);
  EXPECT_EQ(bytes.size(), kMapCodecHeaderBytes + 2000 * kMapCodecLandmarkBytes);
  const MapDecodeResult r = DecodeMap(bytes);
  ASSERT_TRUE(r.ok()) << ToString(r.error);
  ASSERT_EQ(r.map.size(), m.size());
  EXPECT_FLOAT_EQ(static_cast<float>(r.map.shape_sigma_m), 0.25f);
  double worst_cov = 0.0, worst_mm = 0.0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    const Landmark& a = m.landmarks[i];
    const Landmark& b = r.map.landmarks[i];
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(b.signature, -1);  // signatures stay home
    worst_mm = std::max(worst_mm, 1000.0 * (a.mean - b.mean).cwiseAbs().maxCoeff());
    worst_cov = std::max(worst_cov, (a.cov - b.cov).norm() / a.cov.norm());
    EXPECT_TRUE(IsValidCovariance(b.cov));
    EXPECT_GT(b.cov.determinant(), 0.0);
  }
  EXPECT_LE(worst_mm, 0.5 + 1e-6);
  EXPECT_LE(worst_cov, 0.01);
  std::printf("worst position error %.3f mm, worst covariance relative error %.2e\n", worst_mm, worst_cov);
}

TEST(MapCodec, EmptyMapRoundTrips) {
  const MapDecodeResult r = DecodeMap(EncodeMap({}));
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.map.empty());
}

TEST(MapCodec, ExtremesAreClampedIntoValidCovariances) {
  LandmarkMap m;
  m.landmarks.push_back({1, -1, {0.0, 0.0}, Eigen::Matrix2d::Zero()});                       // zero covariance
  m.landmarks.push_back({2, -1, {1.0, 0.0}, (Eigen::Matrix2d() << 1, 1, 1, 1).finished()});  // singular
  m.landmarks.push_back({3, -1, {2.0, 0.0}, 1e8 * Eigen::Matrix2d::Identity()});             // 10 km
  const MapDecodeResult r = DecodeMap(EncodeMap(m));
  ASSERT_TRUE(r.ok());
  for (const Landmark& l : r.map.landmarks) EXPECT_GT(l.cov.determinant(), 0.0);
}

TEST(MapCodec, EncodingRefusesWhatItCannotCarry) {
  LandmarkMap m = RandomMap(3, 5);
  m.landmarks[1].mean.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(EncodeMap(m).empty());
  m = RandomMap(3, 5);
  m.landmarks[1].cov << 1, 2, 2, 1;  // not PSD
  EXPECT_TRUE(EncodeMap(m).empty());
  m = RandomMap(3, 5);
  m.landmarks[1].mean.x() += 20000.0;  // beyond kMapCodecMaxCoordinateM
  MapDecodeError why = MapDecodeError::kOk;
  EXPECT_TRUE(EncodeMap(m, &why).empty());
  EXPECT_EQ(why, MapDecodeError::kOutOfBounds);
  m = RandomMap(3, 5);
  m.landmarks[2].id = m.landmarks[0].id;  // the decoder would refuse it
  EXPECT_TRUE(EncodeMap(m, &why).empty());
  EXPECT_EQ(why, MapDecodeError::kDuplicateId);
  m = RandomMap(kMapCodecMaxLandmarks + 1, 5, 100.0);
  EXPECT_TRUE(EncodeMap(m, &why).empty());
  EXPECT_EQ(why, MapDecodeError::kOversized);
  m.landmarks.pop_back();
  EXPECT_FALSE(EncodeMap(m, &why).empty());
  EXPECT_EQ(why, MapDecodeError::kOk);
}

// A map whose landmarks lie on the bound in every direction is carried; one millimetre
// beyond it is not, on either side of the wire.
TEST(MapCodec, TheCoordinateBoundHoldsOnBothSides) {
  LandmarkMap m;
  const double b = kMapCodecMaxCoordinateM;
  m.landmarks.push_back({1, -1, {-b, -b}, Eigen::Matrix2d::Identity()});
  m.landmarks.push_back({2, -1, {b, b}, Eigen::Matrix2d::Identity()});
  m.landmarks.push_back({3, -1, {b, -b}, Eigen::Matrix2d::Identity()});
  const MapDecodeResult r = DecodeMap(EncodeMap(m));
  ASSERT_TRUE(r.ok()) << ToString(r.error);
  EXPECT_EQ(r.map.landmarks[1].mean, Eigen::Vector2d(b, b));
  m.landmarks[2].mean.x() = b + 0.001;
  EXPECT_TRUE(EncodeMap(m).empty());
}

// What the decoder accepts, the encoder accepts: any payload that decodes re-encodes into one
// that decodes to the very same map (ids, millimetres, covariance codes, shape precision).
void ExpectReEncodes(const LandmarkMap& decoded) {
  MapDecodeError why = MapDecodeError::kOk;
  const auto again = EncodeMap(decoded, &why);
  ASSERT_FALSE(again.empty()) << ToString(why);
  const MapDecodeResult r = DecodeMap(again);
  ASSERT_TRUE(r.ok()) << ToString(r.error);
  ASSERT_EQ(r.map.size(), decoded.size());
  EXPECT_EQ(r.map.shape_sigma_m, decoded.shape_sigma_m);
  for (std::size_t i = 0; i < decoded.size(); ++i) {
    EXPECT_EQ(r.map.landmarks[i].id, decoded.landmarks[i].id);
    EXPECT_EQ(r.map.landmarks[i].mean, decoded.landmarks[i].mean);
    EXPECT_LE((r.map.landmarks[i].cov - decoded.landmarks[i].cov).norm(), 1e-9 * decoded.landmarks[i].cov.norm());
  }
}

TEST(MapCodec, EncoderAndDecoderAcceptTheSameMaps) {
  std::mt19937_64 rng(21);
  int decoded = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    // Random headers and landmark slots, not mutations of a valid payload only: origins and
    // offsets anywhere in their ranges, any codes.
    std::vector<std::uint8_t> bytes = EncodeMap(RandomMap(1 + trial % 5, trial, trial % 2 ? 10.0 : 7000.0));
    for (std::size_t k = 8; k < bytes.size(); ++k) {
      if (rng() % 3 == 0) bytes[k] = static_cast<std::uint8_t>(rng());
    }
    const MapDecodeResult r = DecodeMap(bytes);
    if (!r.ok()) continue;
    ++decoded;
    ExpectReEncodes(r.map);
  }
  EXPECT_GT(decoded, 100);
  // And what the encoder accepts decodes: maps anywhere within the bound.
  for (int trial = 0; trial < 200; ++trial) {
    LandmarkMap m = RandomMap(50, 100 + trial, 2500.0);  // within 2.5 km of (1234.5, -987.6)
    std::uniform_real_distribution<double> shift(-4000.0, 4000.0);
    const Eigen::Vector2d d(shift(rng), shift(rng));
    for (Landmark& l : m.landmarks) l.mean += d;
    const auto bytes = EncodeMap(m);
    ASSERT_FALSE(bytes.empty());
    EXPECT_TRUE(DecodeMap(bytes).ok());
  }
}

class MapCodecRejects : public ::testing::Test {
 protected:
  std::vector<std::uint8_t> good_ = EncodeMap(RandomMap(3, 2));
  std::uint8_t* Slot(std::size_t k) { return good_.data() + kMapCodecHeaderBytes + k * kMapCodecLandmarkBytes; }
  MapDecodeError Decode() { return DecodeMap(good_).error; }
};

TEST_F(MapCodecRejects, Truncated) {
  good_.pop_back();
  EXPECT_EQ(Decode(), MapDecodeError::kTruncated);
  EXPECT_EQ(DecodeMap(std::vector<std::uint8_t>{'M', 'M'}).error, MapDecodeError::kTruncated);
  EXPECT_EQ(DecodeMap(std::vector<std::uint8_t>{'M', 'M', kMapCodecVersion, 0, 1}).error, MapDecodeError::kTruncated);
}

TEST_F(MapCodecRejects, Oversized) {
  good_.push_back(0);
  EXPECT_EQ(Decode(), MapDecodeError::kOversized);
}

TEST_F(MapCodecRejects, CountAboveLimit) {
  const std::uint32_t huge = kMapCodecMaxLandmarks + 1;
  std::memcpy(good_.data() + 4, &huge, 4);
  EXPECT_EQ(Decode(), MapDecodeError::kOversized);
}

TEST_F(MapCodecRejects, BadMagicUnknownVersionAndFlags) {
  auto copy = good_;
  good_[0] = 'X';
  EXPECT_EQ(Decode(), MapDecodeError::kBadMagic);
  good_ = copy;
  good_[2] = 1;  // the 28-byte version 1 is gone
  EXPECT_EQ(Decode(), MapDecodeError::kUnknownVersion);
  good_ = copy;
  good_[3] = 0x80;
  EXPECT_EQ(Decode(), MapDecodeError::kBadHeader);
}

TEST_F(MapCodecRejects, NonFinite) {
  auto copy = good_;
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  std::memcpy(good_.data() + 16, &nan, 4);
  EXPECT_EQ(Decode(), MapDecodeError::kNonFinite);
  std::memcpy(good_.data() + 16, &inf, 4);
  EXPECT_EQ(Decode(), MapDecodeError::kNonFinite);
  good_ = copy;
  const float negative = -1.0f;
  std::memcpy(good_.data() + 16, &negative, 4);
  EXPECT_EQ(Decode(), MapDecodeError::kBadHeader);
  good_ = copy;
  const std::uint16_t invalid = 0xffff;
  std::memcpy(Slot(1) + 12, &invalid, 2);
  EXPECT_EQ(Decode(), MapDecodeError::kNonFinite);
}

TEST_F(MapCodecRejects, NonPositiveDefiniteCovariance) {
  for (std::int16_t code : {std::int16_t{32767}, std::int16_t{-32767}, std::int16_t{-32768}}) {
    auto copy = good_;
    std::memcpy(Slot(2) + 14, &code, 2);
    EXPECT_EQ(Decode(), MapDecodeError::kBadCovariance) << code;
    good_ = copy;
  }
}

TEST_F(MapCodecRejects, DuplicateIds) {
  std::memcpy(Slot(1), Slot(0), 4);
  EXPECT_EQ(Decode(), MapDecodeError::kDuplicateId);
}

TEST_F(MapCodecRejects, OriginOrLandmarkBeyondTheBound) {
  auto copy = good_;
  const std::int32_t far = 2000000000;  // 2000 km: the encoder never sends it
  std::memcpy(good_.data() + 8, &far, 4);
  EXPECT_EQ(Decode(), MapDecodeError::kOutOfBounds);
  good_ = copy;
  const std::int32_t edge = 7999000;  // origin 7.999 km: a landmark 8.3 km beyond it is out
  std::memcpy(good_.data() + 12, &edge, 4);
  const std::uint8_t plus_8300m[3] = {0xE0, 0xA5, 0x7E};  // 8300000 mm, little-endian i24
  std::memcpy(Slot(1) + 7, plus_8300m, 3);
  EXPECT_EQ(Decode(), MapDecodeError::kOutOfBounds);
}

TEST(MapCodec, PayloadCountIsReadFromTheHeader) {
  const auto bytes = EncodeMap(RandomMap(7, 1));
  EXPECT_EQ(MapPayloadCount(bytes), 7u);
  EXPECT_FALSE(MapPayloadCount(std::span<const std::uint8_t>(bytes.data(), 10)).has_value());
}

TEST(MapCodec, RandomBytesNeverCrashAndNeverYieldInvalidMaps) {
  std::mt19937_64 rng(9);
  const auto good = EncodeMap(RandomMap(20, 3));
  int decoded = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    auto bytes = good;
    std::uniform_int_distribution<std::size_t> pos(0, bytes.size() - 1);
    const int flips = 1 + trial % 4;
    for (int k = 0; k < flips; ++k) bytes[pos(rng)] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
    if (trial % 7 == 0) bytes.resize(pos(rng));
    const MapDecodeResult r = DecodeMap(bytes);
    if (!r.ok()) {
      EXPECT_TRUE(r.map.empty());
      continue;
    }
    ++decoded;
    for (const auto& l : r.map.landmarks) {
      EXPECT_TRUE(l.mean.allFinite());
      EXPECT_TRUE(IsValidCovariance(l.cov));
    }
  }
  EXPECT_GT(decoded, 0);
}

}  // namespace
}  // namespace mapmesh
