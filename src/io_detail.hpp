#pragma once
// Internal helpers shared by the readers: whole-file reading, error formatting, byte order.
#include <binpose/io.hpp>
#include <binpose/types.hpp>

#include <bit>
#include <cstdint>
#include <cstring>
#include <fmt/format.h>
#include <string>
#include <string_view>

namespace binpose::detail {

/// Throws binpose::Error("<path>: <message>").
[[noreturn]] void fail(const std::string& path, const std::string& message);

/// The whole file as bytes (throws if it cannot be opened or is empty).
std::string readFileBytes(const std::string& path);

/// Writes `pixels` (rows of `width` pixels of libpng's simplified-API `format`, e.g.
/// PNG_FORMAT_RGB or PNG_FORMAT_LINEAR_Y) as a PNG file; throws binpose::Error on failure.
void writePng(const std::string& path, int width, int height, std::uint32_t format, const void* pixels);

/// A mesh file other than PLY (OFF by binpose, others by assimp) as it stands: its faces may be
/// none (an OBJ of vertices alone, a point cloud), its vertices neither welded nor checked.
Mesh readMeshFile(const std::string& path, double scale);
/// A mesh file's vertices checked (a non-finite one is an error) and identical ones welded.
void weldChecked(const std::string& path, Mesh& mesh);

/// Intrinsics a depth image can be read with: positive finite focal lengths and depth_scale, a
/// finite principal point (else an error naming `path`).
void checkIntrinsics(const std::string& path, const Intrinsics& k);

/// A coordinate beyond this (mm, 100 km) is no measurement: a sensor's marker for a missing depth
/// (the largest float), or a value no float holds.
constexpr double kFarthestMm = 1e8;

/// Lower-cased file extension without the dot ("" when none).
std::string extensionOf(const std::string& path);

/// Splits a header line into whitespace-separated words.
std::vector<std::string_view> splitWords(std::string_view line);

/// Parses a whole token as a number; false when it is not one.
bool parseNumber(std::string_view token, double& value);

/// a * b, or an error naming `what` when the product does not fit in size_t: a size computed
/// from a file's header must not wrap around.
inline std::size_t checkedMul(std::size_t a, std::size_t b, const std::string& path, const char* what) {
  std::size_t product = 0;
  if (__builtin_mul_overflow(a, b, &product)) fail(path, fmt::format("{} overflows ({} x {})", what, a, b));
  return product;
}

/// A whole non-negative integer count of at most `max` from a header token (not 1e30, inf, NaN
/// or 2.5), else an error naming `what`.
std::size_t parseCount(const std::string& path, std::string_view token, const char* what, std::size_t max);

/// The deepest nesting of objects and arrays in a JSON text (brackets inside strings do not
/// count), found without parsing: a crafted file nested 100 000 deep must be refused before a
/// parser or a copy recurses through it.
std::size_t jsonDepth(std::string_view text);
/// The nesting JSON readers accept.
constexpr std::size_t kMostJsonDepth = 64;

/// Scalar types of PLY and PCD.
enum class Scalar { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };
int scalarSize(Scalar type);

/// Reads one scalar of `type` at `data` (byte order `big_endian`) as double.
inline double readScalar(const char* data, Scalar type, bool big_endian) {
  unsigned char bytes[8];
  const int n = scalarSize(type);
  std::memcpy(bytes, data, static_cast<std::size_t>(n));
  if (big_endian != (std::endian::native == std::endian::big)) {
    for (int i = 0; i < n / 2; ++i) std::swap(bytes[i], bytes[n - 1 - i]);
  }
  switch (type) {
    case Scalar::Int8: { std::int8_t v; std::memcpy(&v, bytes, 1); return v; }
    case Scalar::UInt8: { std::uint8_t v; std::memcpy(&v, bytes, 1); return v; }
    case Scalar::Int16: { std::int16_t v; std::memcpy(&v, bytes, 2); return v; }
    case Scalar::UInt16: { std::uint16_t v; std::memcpy(&v, bytes, 2); return v; }
    case Scalar::Int32: { std::int32_t v; std::memcpy(&v, bytes, 4); return v; }
    case Scalar::UInt32: { std::uint32_t v; std::memcpy(&v, bytes, 4); return v; }
    case Scalar::Float32: { float v; std::memcpy(&v, bytes, 4); return v; }
    case Scalar::Float64: { double v; std::memcpy(&v, bytes, 8); return v; }
  }
  return 0.0;
}

}  // namespace binpose::detail
