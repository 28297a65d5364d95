// TIFF depth maps and point maps: the real IC-BIN depth frame written as the TIFFs industrial
// cameras' software exports, read back against its PNG; broken files' one-line errors.
#include <binpose/io.hpp>

#include "test_util.hpp"

#include <tiffio.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

using namespace binpose;
using test::dataPath;
using test::errorOf;

namespace {

/// How a test TIFF is stored.
struct TiffLayout {
  int samples = 1;
  int bits = 32;
  int format = SAMPLEFORMAT_IEEEFP;
  int compression = COMPRESSION_NONE;
  int rows_per_strip = 16;
};

/// Writes width x height pixels of `layout.samples` values each (row-major) with libtiff.
template <typename T>
void writeTiff(const std::string& path, int width, int height, const std::vector<T>& values, const TiffLayout& layout) {
  TIFF* tiff = TIFFOpen(path.c_str(), "w");
  ASSERT_NE(tiff, nullptr);
  TIFFSetField(tiff, TIFFTAG_IMAGEWIDTH, width);
  TIFFSetField(tiff, TIFFTAG_IMAGELENGTH, height);
  TIFFSetField(tiff, TIFFTAG_SAMPLESPERPIXEL, layout.samples);
  TIFFSetField(tiff, TIFFTAG_BITSPERSAMPLE, layout.bits);
  TIFFSetField(tiff, TIFFTAG_SAMPLEFORMAT, layout.format);
  TIFFSetField(tiff, TIFFTAG_PHOTOMETRIC, layout.samples == 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK);
  TIFFSetField(tiff, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tiff, TIFFTAG_COMPRESSION, layout.compression);
  TIFFSetField(tiff, TIFFTAG_ROWSPERSTRIP, layout.rows_per_strip);
  std::vector<T> row(static_cast<std::size_t>(width) * layout.samples);
  for (int v = 0; v < height; ++v) {
    std::copy_n(values.begin() + static_cast<std::ptrdiff_t>(v * row.size()), row.size(), row.begin());
    ASSERT_EQ(TIFFWriteScanline(tiff, row.data(), static_cast<std::uint32_t>(v), 0), 1);
  }
  TIFFClose(tiff);
}

/// IC-BIN frame 0's depth (mm) per pixel from its PNG: 0 where it holds none.
std::vector<float> depthOf(const PointCloud& png, int width, int height) {
  std::vector<float> depth(static_cast<std::size_t>(width) * height, 0.0f);
  for (std::size_t i = 0; i < png.size(); ++i) depth[png.pixel[i]] = png.points[i].z();
  return depth;
}

/// A little-endian TIFF's first directory entry `tag` (SHORT or LONG, one value) set to `value`.
void patchTag(std::string& bytes, std::uint16_t tag, std::uint32_t value) {
  std::uint32_t ifd = 0;
  std::uint16_t count = 0;
  std::memcpy(&ifd, &bytes[4], 4);
  std::memcpy(&count, &bytes[ifd], 2);
  for (std::uint16_t e = 0; e < count; ++e) {
    char* entry = &bytes[ifd + 2 + 12 * e];
    std::uint16_t t = 0, type = 0;
    std::memcpy(&t, entry, 2);
    std::memcpy(&type, entry + 2, 2);
    if (t != tag) continue;
    if (type == TIFF_SHORT) {
      const auto v = static_cast<std::uint16_t>(value);
      std::memcpy(entry + 8, &v, 2);
    } else {
      std::memcpy(entry + 8, &value, 4);
    }
    return;
  }
  FAIL() << "no tag " << tag;
}

void expectSameCloud(const PointCloud& a, const PointCloud& b, float tolerance) {
  ASSERT_EQ(a.size(), b.size());
  ASSERT_EQ(a.pixel, b.pixel);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  for (std::size_t i = 0; i < a.size(); ++i) ASSERT_LE((a.points[i] - b.points[i]).norm(), tolerance) << "point " << i;
}

}  // namespace

TEST(TiffReader, RealDepthFrameAsFloatAndIntegerTiffReadsAsItsPng) {
  REQUIRE_DATA("icbin_mixed/depth/0000.png");
  const Intrinsics camera = readIntrinsics(dataPath("icbin_mixed/camera.json"));
  const PointCloud png = readDepthPng(dataPath("icbin_mixed/depth/0000.png"), camera);
  const int w = png.width, h = png.height;
  ASSERT_EQ(w, 640);
  std::vector<float> depth = depthOf(png, w, h);
  std::vector<std::uint16_t> raw(depth.begin(), depth.end());
  // Float, in mm (as Photoneo and Mech-Mind export), holes as NaN and 0, compressed by Deflate.
  std::vector<float> holes = depth;
  for (std::size_t p = 0; p < holes.size(); p += 2)
    if (holes[p] == 0.0f) holes[p] = NAN;
  const std::string path = test::tempPath("depth.tiff");
  writeTiff(path, w, h, holes, {1, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_ADOBE_DEFLATE, 8});
  expectSameCloud(readDepthTiff(path, camera), png, 0.0f);
  // Float, in metres, read with a depth_scale of 1000.
  std::vector<double> metres(depth.begin(), depth.end());
  for (double& z : metres) z /= 1000.0;
  writeTiff(path, w, h, metres, {1, 64, SAMPLEFORMAT_IEEEFP, COMPRESSION_NONE, 480});
  Intrinsics in_metres = camera;
  in_metres.depth_scale = 1000.0;
  expectSameCloud(readDepthTiff(path, in_metres), png, 1e-3f);
  // 16-bit integers, LZW, one row a strip.
  writeTiff(path, w, h, raw, {1, 16, SAMPLEFORMAT_UINT, COMPRESSION_LZW, 1});
  expectSameCloud(readDepthTiff(path, camera), png, 0.0f);
  EXPECT_NE(errorOf([&] { (void)readCloud(path); }).find("needs the camera's intrinsics"), std::string::npos);
}

TEST(TiffReader, RealFrameAsPointMapGetsItsPixelsAndPinholeBack) {
  REQUIRE_DATA("icbin_mixed/depth/0000.png");
  const Intrinsics camera = readIntrinsics(dataPath("icbin_mixed/camera.json"));
  const PointCloud png = readDepthPng(dataPath("icbin_mixed/depth/0000.png"), camera);
  const int w = png.width, h = png.height;
  std::vector<float> xyz(static_cast<std::size_t>(w) * h * 3, NAN);  // holes: NaN, as Photoneo writes
  for (std::size_t i = 0; i < png.size(); ++i)
    for (int c = 0; c < 3; ++c) xyz[png.pixel[i] * 3 + c] = png.points[i][c];
  const std::string path = test::tempPath("points.tif");
  writeTiff(path, w, h, xyz, {3, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_NONE, 16});
  const PointCloud map = readCloud(path);
  expectSameCloud(map, png, 0.0f);
  EXPECT_NEAR(map.fx, camera.fx, 0.01);  // fitted to the pixels' rays
  EXPECT_NEAR(map.cy, camera.cy, 0.01);
  const PointCloud metres = readTiffPointMap(path, 1000.0);
  EXPECT_NEAR(metres.points[0].z(), 1000.0f * png.points[0].z(), 1e-2f);
  EXPECT_NE(errorOf([&] { (void)readDepthTiff(path, camera); }).find("point map"), std::string::npos);
}

TEST(TiffReader, BrokenFilesGiveOneLineErrors) {
  Intrinsics camera;
  camera.fx = camera.fy = 500.0;
  const std::string path = test::tempPath("broken.tif");
  const auto refusal = [&] {
    const std::string message = errorOf([&] { (void)readDepthTiff(path, camera); });
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    return message;
  };
  const std::vector<std::uint8_t> rgb(3 * 8 * 8, 7);
  writeTiff(path, 8, 8, rgb, {3, 8, SAMPLEFORMAT_UINT, COMPRESSION_NONE, 8});
  EXPECT_NE(refusal().find("8-bit image holds no depth"), std::string::npos);
  const std::vector<float> two(2 * 8 * 8, 1.0f);
  writeTiff(path, 8, 8, two, {2, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_NONE, 8});
  EXPECT_NE(refusal().find("2 values a pixel"), std::string::npos);
  const std::vector<float> depth(64 * 64, 800.0f);
  writeTiff(path, 64, 64, depth, {1, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_NONE, 4});
  const std::string bytes = test::readAll(path);
  EXPECT_EQ(readDepthTiff(path, camera).size(), 64u * 64u);
  std::string large = bytes;  // a header claiming a larger image than the file holds
  patchTag(large, TIFFTAG_IMAGEWIDTH, 5000);
  patchTag(large, TIFFTAG_IMAGELENGTH, 5000);
  test::writeAll(path, large);
  EXPECT_NE(refusal().find("TIFF is truncated (5000 x 5000 pixels"), std::string::npos);
  patchTag(large, TIFFTAG_IMAGEWIDTH, 60000);
  patchTag(large, TIFFTAG_IMAGELENGTH, 60000);
  test::writeAll(path, large);
  EXPECT_NE(refusal().find("larger than this reader allows"), std::string::npos);
  writeTiff(path, 64, 64, depth, {1, 32, SAMPLEFORMAT_IEEEFP, COMPRESSION_NONE, 64});
  std::string moved = test::readAll(path);  // the one strip said to lie past the file's end
  patchTag(moved, TIFFTAG_STRIPOFFSETS, static_cast<std::uint32_t>(moved.size() + 100));
  test::writeAll(path, moved);
  EXPECT_NE(refusal().find("corrupt or truncated TIFF at row 0"), std::string::npos);
  test::writeAll(path, bytes.substr(0, bytes.size() / 2));  // rows missing, the directory at the end gone
  EXPECT_NE(refusal().find("TIFF"), std::string::npos);
  test::writeAll(path, "II*\0garbage");
  EXPECT_NE(refusal().find("not a readable TIFF"), std::string::npos);
  test::writeAll(path, "");
  EXPECT_NE(refusal().find(path), std::string::npos);
  camera.fx = 0.0;
  EXPECT_NE(refusal().find("focal lengths"), std::string::npos);
}
