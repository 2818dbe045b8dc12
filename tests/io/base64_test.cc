#include "common/io/base64.h"

#include <gtest/gtest.h>

#include <random>

namespace mapmesh::io {
namespace {

std::vector<std::uint8_t> Bytes(std::string_view s) { return {s.begin(), s.end()}; }

// RFC 4648, section 10.
TEST(Base64, TheRfcsTestVectors) {
  const std::pair<const char*, const char*> vectors[] = {{"", ""},
                                                         {"f", "Zg=="},
                                                         {"fo", "Zm8="},
                                                         {"foo", "Zm9v"},
                                                         {"foob", "Zm9vYg=="},
                                                         {"fooba", "Zm9vYmE="},
                                                         {"foobar", "Zm9vYmFy"}};
  for (const auto& [plain, coded] : vectors) {
    EXPECT_EQ(Base64Encode(Bytes(plain)), coded) << plain;
    const auto back = Base64Decode(coded);
    ASSERT_TRUE(back.has_value()) << coded;
    EXPECT_EQ(*back, Bytes(plain)) << coded;
  }
}

TEST(Base64, RandomBytesRoundTrip) {
  std::mt19937_64 rng(41);
  std::uniform_int_distribution<int> byte(0, 255);
  for (std::size_t n = 0; n < 200; ++n) {
    std::vector<std::uint8_t> b(n);
    for (auto& x : b) x = static_cast<std::uint8_t>(byte(rng));
    const std::string text = Base64Encode(b);
    EXPECT_EQ(text.size(), 4 * ((n + 2) / 3));
    const auto back = Base64Decode(text);
    ASSERT_TRUE(back.has_value()) << n;
    EXPECT_EQ(*back, b) << n;
  }
}

TEST(Base64, WhatIsNotPaddedBase64IsRefused) {
  for (const char* bad : {"Zg=", "Zg", "Zm9", "Z===", "====", "Zm=v", "Zg==Zg==", "Zm9v\n", " Zm9v", "Zm9v ", "Zm 9",
                          "Zm9-", "Zm9_", "Zm9\x80"}) {
    EXPECT_FALSE(Base64Decode(bad).has_value()) << bad;
  }
}

}  // namespace
}  // namespace mapmesh::io
