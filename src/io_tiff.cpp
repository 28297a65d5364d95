// TIFF depth maps and point maps, as industrial 3-D cameras' software exports them (Photoneo,
// Mech-Mind, Ensenso, Basler): one value a pixel (a depth, 16- or 32-bit integer or float) or
// three (x, y, z, float), stored in strips, read with libtiff.
#include "io_detail.hpp"

#include <binpose/io.hpp>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <tiffio.h>

namespace binpose {
namespace {

using detail::fail;
using detail::Scalar;

/// The most pixels a map may have (a 12-megapixel sensor has a third of this).
constexpr std::size_t kMostPixels = std::size_t{1} << 25;
/// The most bytes libtiff may allocate at once, and the most a row may hold.
constexpr tmsize_t kMostAllocation = tmsize_t{1} << 30;
/// Deflate and LZW expand a file at most a few thousand times: an image claiming more bytes than
/// that of its file is refused before its rows are read.
constexpr std::size_t kMostExpansion = 4096;

/// libtiff's first error message, kept for the one-line error; warnings (unknown tags) are not
/// errors.
int keepError(TIFF*, void* user, const char*, const char* format, va_list args) {
  auto* message = static_cast<std::string*>(user);
  if (message->empty()) {
    char text[256];
    std::vsnprintf(text, sizeof text, format, args);
    *message = text;
  }
  return 1;
}
int ignoreWarning(TIFF*, void*, const char*, const char*, va_list) { return 1; }

struct TiffClose {
  void operator()(TIFF* tiff) const { TIFFClose(tiff); }
};

/// The scalar type of the file's samples (SampleFormat and BitsPerSample).
Scalar sampleType(const std::string& path, std::uint16_t format, std::uint16_t bits) {
  if (format == SAMPLEFORMAT_IEEEFP && bits == 32) return Scalar::Float32;
  if (format == SAMPLEFORMAT_IEEEFP && bits == 64) return Scalar::Float64;
  if (format == SAMPLEFORMAT_UINT && bits == 16) return Scalar::UInt16;
  if (format == SAMPLEFORMAT_UINT && bits == 32) return Scalar::UInt32;
  if (format == SAMPLEFORMAT_INT && bits == 16) return Scalar::Int16;
  if (format == SAMPLEFORMAT_INT && bits == 32) return Scalar::Int32;
  if (bits == 8) fail(path, "an 8-bit image holds no depth (a picture?): a depth map has 16 or 32 bits a value");
  fail(path,
       fmt::format("samples of {} bits in format {} are not read (16- or 32-bit integers, 32- or 64-bit floats)", bits, format));
}

/// An open TIFF map (its first page), checked before any row is read: its size, its values a
/// pixel (`samples`) and their type; rows are read one at a time as doubles in the file's units.
class TiffMap {
 public:
  explicit TiffMap(const std::string& path) : path_(path) {
    TIFFOpenOptions* options = TIFFOpenOptionsAlloc();
    TIFFOpenOptionsSetMaxSingleMemAlloc(options, kMostAllocation);
    TIFFOpenOptionsSetErrorHandlerExtR(options, keepError, &error_);
    TIFFOpenOptionsSetWarningHandlerExtR(options, ignoreWarning, nullptr);
    tiff_.reset(TIFFOpenExt(path.c_str(), "r", options));
    TIFFOpenOptionsFree(options);
    if (!tiff_) fail(path, error_.empty() ? std::string("not a readable TIFF") : "not a readable TIFF (" + error_ + ")");
    checkLayout();
  }
  int width = 0, height = 0, samples = 0;

  /// Row v's width * samples values.
  void readRow(int v, std::vector<double>& values) {
    if (TIFFReadScanline(tiff_.get(), row_.data(), static_cast<std::uint32_t>(v), 0) < 0)
      fail(path_, fmt::format("corrupt or truncated TIFF at row {} ({})", v, error_.empty() ? "no data" : error_));
    const int size = detail::scalarSize(type_);
    values.resize(std::size_t(width) * samples);
    for (std::size_t i = 0; i < values.size(); ++i)  // libtiff gives the machine's byte order
      values[i] = detail::readScalar(&row_[i * size], type_, std::endian::native == std::endian::big);
  }

 private:
  void checkLayout() {
    std::uint32_t w = 0, h = 0;
    std::uint16_t spp = 1, bits = 1, format = SAMPLEFORMAT_UINT, planar = PLANARCONFIG_CONTIG;
    TIFFGetField(tiff_.get(), TIFFTAG_IMAGEWIDTH, &w);
    TIFFGetField(tiff_.get(), TIFFTAG_IMAGELENGTH, &h);
    TIFFGetFieldDefaulted(tiff_.get(), TIFFTAG_SAMPLESPERPIXEL, &spp);
    TIFFGetFieldDefaulted(tiff_.get(), TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFGetFieldDefaulted(tiff_.get(), TIFFTAG_SAMPLEFORMAT, &format);
    TIFFGetFieldDefaulted(tiff_.get(), TIFFTAG_PLANARCONFIG, &planar);
    if (w == 0 || h == 0) fail(path_, "TIFF has an empty image");
    if (std::size_t{w} * h > kMostPixels)
      fail(path_, fmt::format("image of {} x {} pixels is larger than this reader allows", w, h));
    if (spp != 1 && spp != 3 && spp != 4)
      fail(path_, fmt::format("{} values a pixel: a depth map has 1, a point map 3 (x, y, z)", spp));
    type_ = sampleType(path_, format, bits);
    if (TIFFIsTiled(tiff_.get())) fail(path_, "a tiled TIFF is not read (save it in strips)");
    if (spp > 1 && planar != PLANARCONFIG_CONTIG) fail(path_, "separate planes are not read (save x, y, z interleaved)");
    const std::uint64_t row_bytes = std::uint64_t{w} * spp * static_cast<std::uint64_t>(detail::scalarSize(type_));
    if (TIFFScanlineSize64(tiff_.get()) != row_bytes) fail(path_, "TIFF rows do not hold their pixels' values");
    std::error_code ec;
    const std::uintmax_t file_bytes = std::filesystem::file_size(path_, ec);
    if (ec || row_bytes * h > kMostExpansion * file_bytes + 4096)
      fail(path_, fmt::format("TIFF is truncated ({} x {} pixels in a file of {} bytes)", w, h, ec ? 0 : file_bytes));
    width = static_cast<int>(w);
    height = static_cast<int>(h);
    samples = spp;
    row_.resize(row_bytes);
  }

  std::string path_, error_;
  std::unique_ptr<TIFF, TiffClose> tiff_;
  Scalar type_{};
  std::vector<char> row_;
};

}  // namespace

PointCloud readDepthTiff(const std::string& path, const Intrinsics& k) {
  detail::checkIntrinsics(path, k);
  TiffMap map(path);
  if (map.samples != 1) fail(path, "the TIFF holds x, y, z a pixel (a point map): read it without intrinsics");
  if (k.width > 0 && k.height > 0 && (k.width != map.width || k.height != map.height))
    fail(path, fmt::format("image is {}x{} but the intrinsics say {}x{}", map.width, map.height, k.width, k.height));
  std::vector<float> depth(std::size_t(map.width) * map.height);
  std::vector<double> row;
  for (int v = 0; v < map.height; ++v) {
    map.readRow(v, row);
    for (int u = 0; u < map.width; ++u)  // a value no float holds (a 64-bit marker) is none
      depth[std::size_t(v) * map.width + u] = std::abs(row[u]) <= std::numeric_limits<float>::max() ? float(row[u]) : NAN;
  }
  return depthToCloud(depth, map.width, map.height, k);  // NaN, 0 or below, beyond kFarthestMm: none
}

PointCloud readTiffPointMap(const std::string& path, double scale) {
  TiffMap map(path);
  if (map.samples == 1)
    fail(path, "the TIFF holds one value a pixel (a depth map): it needs the camera's intrinsics (--intrinsics)");
  Points xyz(std::size_t(map.width) * map.height, Vec3::Zero());
  std::vector<double> row;
  for (int v = 0; v < map.height; ++v) {
    map.readRow(v, row);
    for (int u = 0; u < map.width; ++u) {
      const double* x = &row[std::size_t(u) * map.samples];
      if (std::abs(x[0] * scale) < detail::kFarthestMm && std::abs(x[1] * scale) < detail::kFarthestMm &&
          std::abs(x[2] * scale) < detail::kFarthestMm)  // else NaN, infinite, or a missing point's marker: none
        xyz[std::size_t(v) * map.width + u] = Vec3(float(x[0] * scale), float(x[1] * scale), float(x[2] * scale));
    }
  }
  PointCloud cloud = pointMapToCloud(xyz, map.width, map.height);
  if (cloud.empty()) fail(path, "no point in the file");
  return cloud;
}

bool isTiffPath(const std::string& path) {
  const std::string ext = detail::extensionOf(path);
  return ext == "tif" || ext == "tiff";
}

}  // namespace binpose
