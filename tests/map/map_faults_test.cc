#include "common/map/map_faults.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace mapmesh {
namespace {

LandmarkMap RandomMap(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-60.0, 60.0), s(0.01, 2.0), r(-0.9, 0.9);
  LandmarkMap m;
  m.shape_sigma_m = 0.1;
  for (int i = 0; i < n; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(7 * i + 3);
    l.mean = {u(rng), u(rng)};
    const double sx = s(rng), sy = s(rng), rho = r(rng);
    l.cov << sx * sx, rho * sx * sy, rho * sx * sy, sy * sy;
    m.landmarks.push_back(l);
  }
  return m;
}

class PayloadFaults : public ::testing::TestWithParam<std::uint64_t> {};

TEST_P(PayloadFaults, EachFaultIsRefusedForItsOwnReason) {
  std::mt19937_64 rng(GetParam());
  const LandmarkMap m = RandomMap(2 + static_cast<int>(rng() % 60), rng);
  const std::vector<std::uint8_t> good = EncodeMap(m);
  ASSERT_TRUE(DecodeMap(good).ok());
  for (int i = 0; i < kPayloadFaultCount; ++i) {
    const auto f = static_cast<PayloadFault>(i);
    const std::vector<std::uint8_t> bad = CorruptPayload(good, f);
    EXPECT_NE(bad, good) << ToString(f);
    EXPECT_EQ(DecodeMap(bad).error, ExpectedDecodeError(f)) << ToString(f);
    EXPECT_NE(ExpectedDecodeError(f), MapDecodeError::kOk);
  }
}

INSTANTIATE_TEST_SUITE_P(Seeds, PayloadFaults, ::testing::Range<std::uint64_t>(1, 21));

TEST(PayloadFaults, NamesRoundTripAndUnknownNamesAreRefused) {
  for (int i = 0; i < kPayloadFaultCount; ++i) {
    const auto f = static_cast<PayloadFault>(i);
    EXPECT_EQ(PayloadFaultFromString(ToString(f)), f);
  }
  EXPECT_FALSE(PayloadFaultFromString("truncate").has_value());
  EXPECT_FALSE(PayloadFaultFromString("").has_value());
}

TEST(PayloadFaults, EveryDecodeErrorCanBeInjected) {
  std::vector<bool> reached(kMapDecodeErrorCount, false);
  for (int i = 0; i < kPayloadFaultCount; ++i)
    reached[static_cast<int>(ExpectedDecodeError(static_cast<PayloadFault>(i)))] = true;
  for (int e = 1; e < kMapDecodeErrorCount; ++e) EXPECT_TRUE(reached[e]) << ToString(static_cast<MapDecodeError>(e));
}

TEST(ShuffleCoordinates, KeepsIdsCovariancesAndEachAxisButMovesTheLandmarks) {
  std::mt19937_64 rng(4);
  const LandmarkMap m = RandomMap(40, rng);
  const LandmarkMap s = ShuffleCoordinates(m, rng);
  ASSERT_EQ(s.size(), m.size());
  std::vector<double> xs, ys, sxs, sys;
  int moved = 0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    EXPECT_EQ(s.landmarks[i].id, m.landmarks[i].id);
    EXPECT_EQ(s.landmarks[i].cov, m.landmarks[i].cov);
    xs.push_back(m.landmarks[i].mean.x());
    ys.push_back(m.landmarks[i].mean.y());
    sxs.push_back(s.landmarks[i].mean.x());
    sys.push_back(s.landmarks[i].mean.y());
    if ((s.landmarks[i].mean - m.landmarks[i].mean).norm() > 1e-9) ++moved;
  }
  for (auto* v : {&xs, &ys, &sxs, &sys}) std::sort(v->begin(), v->end());
  EXPECT_EQ(xs, sxs);
  EXPECT_EQ(ys, sys);
  EXPECT_GE(moved, 36);  // two independent permutations leave almost no landmark in place
  EXPECT_TRUE(DecodeMap(EncodeMap(s)).ok());
}

}  // namespace
}  // namespace mapmesh
