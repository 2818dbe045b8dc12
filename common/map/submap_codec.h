#pragma once
// Closed submaps as they travel (issue J1): immutable, named by who made them (robot,
// incarnation, index in that incarnation's chain), holding their estimate in their own frame
// (the robot's pose when the submap opened): x = [end pose (x, y, theta); landmark means
// (2 each)], its joint covariance p, and the robot's ids of those landmarks. A submap is
// independent of every other (it starts from no prior), so a receiver may join it with any
// other exactly once; its identity lets every robot relay it and refuse it a second time.
//
// Version 1 layout (little-endian). Header, 36 bytes: magic "MS", u8 version = 1, u8 flags = 0,
// u32 robot, u32 incarnation, u32 index, f64 opened_s, f64 closed_s, u32 count. Then count u32
// landmark ids; the 3 + 2 count entries of x as f64; and the lower triangle of p's Cholesky
// factor L (p = L L^T), row by row, as f32: a decoded covariance is positive definite by
// construction (L's diagonal must be positive). A submap of n landmarks takes
// 36 + 4 n + 8 (3 + 2 n) + 2 (3 + 2 n)(4 + 2 n) bytes (30 landmarks: 8.8 kB).
//
// As the map codec: the encoder and the decoder accept exactly the same submaps, and a decoded
// submap re-encodes to the same bytes, so that a relayed submap is byte for byte the one its
// robot sent and two different submaps under one identity are told apart by their bytes.
//
// Pure: no DDS, clocks or random numbers.

#include <Eigen/Core>
#include <compare>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "common/types/messages.h"

namespace mapmesh {

struct SubmapId {
  RobotId robot = 0;
  std::uint32_t incarnation = 0;
  std::uint32_t index = 0;  // place in the incarnation's chain of submaps, from 0
  friend auto operator<=>(const SubmapId&, const SubmapId&) = default;
};

struct WireSubmap {
  SubmapId id;
  double opened_s = 0.0;                         // scenario time at which the submap opened (its frame's origin) ...
  double closed_s = 0.0;                         // ... and closed
  std::vector<std::uint32_t> keys;               // the robot's landmark ids, distinct, in x's order
  Eigen::VectorXd x = Eigen::VectorXd::Zero(3);  // [end pose; landmark means], 3 + 2 keys
  // The covariance's lower Cholesky factor (p = l l^T), with entries as the wire holds them
  // (f32), so that the sender's copy and every receiver's are the same: set it with
  // SetCovariance.
  Eigen::MatrixXd l = Eigen::MatrixXd::Identity(3, 3);

  // l from a covariance; false (l unchanged) when p is not symmetric positive definite.
  bool SetCovariance(const Eigen::MatrixXd& p);
  Eigen::MatrixXd Covariance() const { return l * l.transpose(); }
};

inline constexpr std::uint8_t kSubmapCodecVersion = 1;
inline constexpr std::size_t kSubmapCodecHeaderBytes = 36;
// Neither side accepts a submap of more landmarks than this (its covariance grows with the
// square) ...
inline constexpr std::uint32_t kSubmapCodecMaxLandmarks = 500;
// ... nor a coordinate farther than this from the submap frame's origin (m), as the map codec.
inline constexpr double kSubmapCodecMaxCoordinateM = 8000.0;

enum class SubmapDecodeError {
  kOk = 0,
  kTruncated,       // shorter than its header or its count says
  kOversized,       // longer than its count says, or count above the limit
  kBadMagic,        // not a submap of this codec
  kUnknownVersion,  //
  kBadHeader,       // unknown flags, or stamps not finite or closing before opening
  kNonFinite,       // a NaN or inf in x or L
  kBadCovariance,   // L's diagonal not positive, or denormal (the covariance would not be positive definite)
  kDuplicateId,     // one landmark id twice
  kOutOfBounds,     // a coordinate beyond kSubmapCodecMaxCoordinateM
};
inline constexpr int kSubmapDecodeErrorCount = 10;

std::string_view ToString(SubmapDecodeError e);

// The bytes a submap of `landmarks` landmarks takes.
std::size_t SubmapPayloadBytes(std::uint32_t landmarks);
// The most landmarks a submap of at most `bytes` bytes holds (0 when not even an empty one fits;
// at most kSubmapCodecMaxLandmarks).
std::uint32_t SubmapLandmarksWithin(std::size_t bytes);

// Encodes a submap; fails (empty, the reason in *error when given) when the sizes disagree, the
// ids repeat, a value is not finite, l is not lower triangular with a positive diagonal, a
// coordinate is out of bounds, the stamps are not ordered, or it has too many landmarks. l's
// entries are written as f32.
std::vector<std::uint8_t> EncodeSubmap(const WireSubmap& submap, SubmapDecodeError* error = nullptr);

struct SubmapDecodeResult {
  SubmapDecodeError error = SubmapDecodeError::kOk;
  WireSubmap submap;  // valid only when ok()
  bool ok() const { return error == SubmapDecodeError::kOk; }
};

// Decodes and validates a payload; never throws, never crashes on malformed input.
SubmapDecodeResult DecodeSubmap(std::span<const std::uint8_t> payload);

}  // namespace mapmesh
