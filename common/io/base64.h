#pragma once
// Base64 (RFC 4648, the standard alphabet, with padding) for binary data inside JSON run files,
// by OpenSSL's block codec: a checkpoint's submaps are kept as they travel (issue J1).

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace mapmesh::io {

std::string Base64Encode(std::span<const std::uint8_t> bytes);

// The bytes, or nullopt when the text is not padded base64: a length that is not a multiple of
// 4, a character outside the alphabet (whitespace included), or '=' other than one or two at
// the end.
std::optional<std::vector<std::uint8_t>> Base64Decode(std::string_view text);

}  // namespace mapmesh::io
