#include "common/map/map_codec.h"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <random>

namespace mapmesh {
namespace {

LandmarkMap RandomMap(int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-500, 500), us(0.01, 2.0), ur(-0.9, 0.9);
  LandmarkMap m;
  for (int i = 0; i < n; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(3 * i + 1);
    l.signature = i % 3 == 0 ? -1 : i;
    l.mean = {u(rng), u(rng)};
    const double sx = us(rng), sy = us(rng), rho = ur(rng);
    l.cov << sx * sx, rho * sx * sy, rho * sx * sy, sy * sy;
    m.landmarks.push_back(l);
  }
  return m;
}

TEST(MapCodec, RoundTripKeepsMillimetresAndCovariances) {
  const LandmarkMap m = RandomMap(500, 1);
  const auto bytes = EncodeMap(m);
  EXPECT_EQ(bytes.size(), kMapCodecHeaderBytes + 500 * kMapCodecLandmarkBytes);
  const MapDecodeResult r = DecodeMap(bytes);
  ASSERT_TRUE(r.ok()) << ToString(r.error);
  ASSERT_EQ(r.map.size(), m.size());
  for (std::size_t i = 0; i < m.size(); ++i) {
    const Landmark& a = m.landmarks[i];
    const Landmark& b = r.map.landmarks[i];
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.signature, b.signature);
    EXPECT_LE((a.mean - b.mean).cwiseAbs().maxCoeff(), 0.0005 + 1e-12);
    EXPECT_LE((a.cov - b.cov).norm() / a.cov.norm(), 1e-6);
  }
}

TEST(MapCodec, EmptyMapRoundTrips) {
  const MapDecodeResult r = DecodeMap(EncodeMap({}));
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r.map.empty());
}

class MapCodecRejects : public ::testing::Test {
 protected:
  std::vector<std::uint8_t> good_ = EncodeMap(RandomMap(3, 2));
  void SetFloat(std::size_t landmark, std::size_t field_offset, float v) {
    std::memcpy(good_.data() + kMapCodecHeaderBytes + landmark * kMapCodecLandmarkBytes + field_offset, &v, 4);
  }
  MapDecodeError Decode() { return DecodeMap(good_).error; }
};

TEST_F(MapCodecRejects, Truncated) {
  good_.pop_back();
  EXPECT_EQ(Decode(), MapDecodeError::kTruncated);
  EXPECT_EQ(DecodeMap(std::vector<std::uint8_t>{'M', 'M', 1}).error, MapDecodeError::kTruncated);
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

TEST_F(MapCodecRejects, BadMagicAndUnknownVersion) {
  auto copy = good_;
  good_[0] = 'X';
  EXPECT_EQ(Decode(), MapDecodeError::kBadMagic);
  good_ = copy;
  good_[2] = 99;
  EXPECT_EQ(Decode(), MapDecodeError::kUnknownVersion);
}

TEST_F(MapCodecRejects, NonFinite) {
  SetFloat(1, 16, std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(Decode(), MapDecodeError::kNonFinite);
  good_ = EncodeMap(RandomMap(3, 2));
  SetFloat(2, 24, std::numeric_limits<float>::infinity());
  EXPECT_EQ(Decode(), MapDecodeError::kNonFinite);
}

TEST_F(MapCodecRejects, NonPsdCovariance) {
  SetFloat(0, 16, 1.0f);   // cxx
  SetFloat(0, 20, 5.0f);   // cxy: |cxy| > sqrt(cxx cyy)
  SetFloat(0, 24, 1.0f);   // cyy
  EXPECT_EQ(Decode(), MapDecodeError::kBadCovariance);
  SetFloat(0, 16, -1.0f);
  SetFloat(0, 20, 0.0f);
  EXPECT_EQ(Decode(), MapDecodeError::kBadCovariance);
}

TEST_F(MapCodecRejects, DuplicateIds) {
  std::memcpy(good_.data() + kMapCodecHeaderBytes + kMapCodecLandmarkBytes,
              good_.data() + kMapCodecHeaderBytes, 4);
  EXPECT_EQ(Decode(), MapDecodeError::kDuplicateId);
}

TEST(MapCodec, RandomBytesNeverCrash) {
  std::mt19937_64 rng(9);
  std::uniform_int_distribution<int> byte(0, 255), len(0, 200);
  int accepted = 0;
  for (int i = 0; i < 2000; ++i) {
    std::vector<std::uint8_t> b(len(rng));
    for (auto& x : b) x = static_cast<std::uint8_t>(byte(rng));
    if (b.size() >= 3 && i % 2 == 0) {
      b[0] = 'M';
      b[1] = 'M';
      b[2] = 1;
    }
    const MapDecodeResult r = DecodeMap(b);
    if (r.ok()) {
      ++accepted;
      for (const Landmark& l : r.map.landmarks) EXPECT_TRUE(IsValidCovariance(l.cov));
    } else {
      EXPECT_TRUE(r.map.empty());
    }
  }
  EXPECT_LT(accepted, 2000);
}

TEST(IsValidCovariance, Cases) {
  Eigen::Matrix2d c;
  c << 1, 0.5, 0.5, 1;
  EXPECT_TRUE(IsValidCovariance(c));
  c << 1, 0.5, 0.4, 1;
  EXPECT_FALSE(IsValidCovariance(c));  // not symmetric
  c << 0, 0, 0, 0;
  EXPECT_TRUE(IsValidCovariance(c));  // singular is PSD
  c << 1, 2, 2, 1;
  EXPECT_FALSE(IsValidCovariance(c));
}

}  // namespace
}  // namespace mapmesh
