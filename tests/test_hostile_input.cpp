// Crafted files: each is refused with one line naming the file and the problem, before anything
// sized by its header is allocated, or read exactly.
#include <binpose/io.hpp>
#include <binpose/model_database.hpp>
#include <binpose/shapes.hpp>
#include <binpose/params.hpp>

#include "test_util.hpp"

#include <zlib.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <string>

using namespace binpose;

namespace {

/// The message of the binpose::Error `read` throws ("" when it throws none), in under a second.
template <class Read>
std::string refusal(Read read) {
  const auto t0 = std::chrono::steady_clock::now();
  std::string message;
  try {
    read();
  } catch (const Error& e) {
    message = e.what();
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 1.0);
  return message;
}

/// `text` into a temporary file named `name`; its path.
std::string fileWith(const std::string& name, const std::string& text) {
  const std::string path = test::tempPath(name);
  test::writeAll(path, text);
  return path;
}

std::string bigEndian(std::uint32_t v) {
  return {char(v >> 24), char(v >> 16), char(v >> 8), char(v)};
}

std::string chunk(const std::string& type, const std::string& data) {
  const std::string body = type + data;
  const auto crc = static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(body.data()), uInt(body.size())));
  return bigEndian(std::uint32_t(data.size())) + body + bigEndian(crc);
}

/// A PNG of `width` x `height` 16-bit samples (one channel, or grey + alpha for colour type 4),
/// every sample `value`, with `extra` chunks before the image data.
std::string png(std::uint32_t width, std::uint32_t height, int colour_type, std::uint16_t value, const std::string& extra = "") {
  const int channels = colour_type == 4 ? 2 : 1;
  std::string raw;
  for (std::uint32_t y = 0; y < height; ++y) {
    raw += '\0';  // no filter
    for (std::uint32_t x = 0; x < width * std::uint32_t(channels); ++x) raw += {char(value >> 8), char(value & 0xff)};
  }
  uLongf size = compressBound(uLong(raw.size()));
  std::string packed(size, '\0');
  compress2(reinterpret_cast<Bytef*>(packed.data()), &size, reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()), 9);
  packed.resize(size);
  const std::string header = bigEndian(width) + bigEndian(height) + std::string{char(16), char(colour_type), 0, 0, 0};
  return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", header) + extra + chunk("IDAT", packed) + chunk("IEND", "");
}

Intrinsics camera() {
  Intrinsics k;
  k.fx = k.fy = 500;
  k.cx = k.cy = 2;
  return k;
}

}  // namespace

TEST(HostileInput, PcdWhosePointSizeOverflowsIsRefused) {
  std::string fields = "FIELDS x y z", size = "SIZE 4 4 4", type = "TYPE F F F", count = "COUNT 1 1 1";
  for (int i = 0; i < 257; ++i) fields += " p", size += " 8", type += " F", count += " 2147483647";
  const std::string header = "VERSION .7\n" + fields + " w\n" + size + " 4\n" + type + " F\n" + count +
                             " 1\nWIDTH 4194304\nHEIGHT 1\nPOINTS 4194304\nDATA binary\n";
  for (const char* data : {"binary\n", "binary_compressed\n"}) {
    std::string text = header;
    text.replace(text.rfind("binary\n"), 7, data);
    const std::string path = fileWith("overflow.pcd", text + std::string(48, '\0'));
    const std::string m = refusal([&] { (void)readPcd(path); });
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_NE(m.find("COUNT"), std::string::npos) << m;
  }
}

TEST(HostileInput, PcdClaimingMorePointsThanItHoldsIsRefusedBeforeAllocating) {
  const std::string head = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n";
  const std::string many = fileWith("many.pcd", head + "WIDTH 200000000\nHEIGHT 1\nPOINTS 200000000\nDATA binary\n" + std::string(36, '\0'));
  EXPECT_NE(refusal([&] { (void)readPcd(many); }).find("truncated"), std::string::npos);
  const std::string text = fileWith("many_ascii.pcd", head + "WIDTH 200000000\nHEIGHT 1\nPOINTS 200000000\nDATA ascii\n1 2 3\n");
  EXPECT_NE(refusal([&] { (void)readPcd(text); }).find("truncated"), std::string::npos);
  const std::string wrapped = fileWith("wrapped.pcd", head + "WIDTH 2147418113\nHEIGHT 8590196740\nPOINTS 4\nDATA binary\n" + std::string(48, '\0'));
  EXPECT_NE(refusal([&] { (void)readPcd(wrapped); }).find("HEIGHT"), std::string::npos);
  const std::string huge = fileWith("huge.pcd", head + "WIDTH 4e9\nHEIGHT 1\nPOINTS 4e9\nDATA binary\n");
  EXPECT_NE(refusal([&] { (void)readPcd(huge); }).find("whole number"), std::string::npos);
  const std::uint32_t claimed = 12 * 1000000;  // a million points from 4 compressed bytes
  const std::string block = std::string{char(4), 0, 0, 0} + std::string{char(claimed & 0xff), char(claimed >> 8 & 0xff), char(claimed >> 16 & 0xff), char(claimed >> 24)} + "abcd";
  const std::string lzf = fileWith("lzf.pcd", head + "WIDTH 1000000\nHEIGHT 1\nPOINTS 1000000\nDATA binary_compressed\n" + block);
  EXPECT_NE(refusal([&] { (void)readPcd(lzf); }).find("cannot hold"), std::string::npos);
}

TEST(HostileInput, PlyWithTwoVertexElementsOrBadCountsIsRefused) {
  const std::string two = fileWith("two.ply",
                                   "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                                   "property float nx\nproperty float ny\nproperty float nz\nelement vertex 3\nproperty float x\n"
                                   "property float y\nproperty float z\nend_header\n0 0 0 0 0 1\n1 2 3\n4 5 6\n7 8 9\n");
  EXPECT_NE(refusal([&] { (void)readPlyCloud(two); }).find("two 'vertex' elements"), std::string::npos);
  for (const char* count : {"1e30", "inf", "nan", "-1", "2.5"}) {
    const std::string path = fileWith("count.ply", std::string("ply\nformat ascii 1.0\nelement vertex ") + count +
                                                       "\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n");
    EXPECT_NE(refusal([&] { (void)readPlyCloud(path); }).find("whole number"), std::string::npos) << count;
  }
  const std::string many = fileWith("many.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\n"
                                                "property float x\nproperty float y\nproperty float z\nend_header\n" + std::string(12, '\0'));
  EXPECT_NE(refusal([&] { (void)readPlyCloud(many); }).find("truncated"), std::string::npos);
  const std::string list = fileWith("list.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                                "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                                "0 0 0\n1 0 0\n0 1 0\nnan 0 1 2\n");
  EXPECT_NE(refusal([&] { (void)readModelFile(list); }).find("invalid list length"), std::string::npos);
  // A face's other list (texture coordinates, say) may hold any values: skipped, not cast to int.
  const std::string other = fileWith("other.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                                  "property float z\nelement face 1\nproperty list uchar uint texcoord\n"
                                                  "property list uchar int vertex_indices\nend_header\n"
                                                  "0 0 0\n1 0 0\n0 1 0\n2 4278190080 7 3 2 0 1\n");
  const Mesh mesh = readPlyMesh(other);
  ASSERT_EQ(mesh.faces.size(), 1u);
  EXPECT_EQ(mesh.faces[0], Eigen::Vector3i(2, 0, 1));
}

// Elements without properties hold no data, so no body length bounds their counts: they are
// passed over without a loop over their claimed count (which hung the reader for seconds).
TEST(HostileInput, PlyElementsWithoutPropertiesAreSkipped) {
  std::string header = "ply\nformat ascii 1.0\n";
  for (int i = 0; i < 64; ++i) header += "element empty" + std::to_string(i) + " 2147483647\n";
  const std::string path = fileWith("empty.ply", header + "element vertex 1\nproperty float x\nproperty float y\n"
                                                          "property float z\nend_header\n1 2 3\n");
  const PointCloud cloud = readPlyCloud(path, 1.0);
  ASSERT_EQ(cloud.points.size(), 1u);
  EXPECT_EQ(cloud.points[0], Vec3(1, 2, 3));
}

TEST(HostileInput, CameraJsonNestedDeeplyOrHugeIsRefused) {
  std::string deep;
  for (int i = 0; i < 100000; ++i) deep += "{\"a\":";
  deep += "1";
  for (int i = 0; i < 100000; ++i) deep += "}";
  const std::string path = fileWith("deep.json", deep);
  EXPECT_NE(refusal([&] { (void)readIntrinsics(path); }).find("nested too deeply"), std::string::npos);
  EXPECT_NE(refusal([&] { (void)readIntrinsics(path, "a"); }).find("nested too deeply"), std::string::npos);
  DetectionParams p;
  EXPECT_NE(refusal([&] { applyJson(p, deep, "params.json"); }).find("nested too deeply"), std::string::npos);
  const std::string wide = fileWith("wide.json", R"({"fx": 500, "fy": 500, "cx": 2, "cy": 2, "width": 1e30, "height": 4})");
  EXPECT_NE(refusal([&] { (void)readIntrinsics(wide); }).find("width"), std::string::npos);
}

TEST(HostileInput, DepthPngIsReadExactlyOrRefused) {
  const std::string linear = fileWith("linear.png", png(4, 4, 0, 5000, chunk("gAMA", bigEndian(100000))));
  const PointCloud c = readDepthPng(linear, camera());
  ASSERT_EQ(c.size(), 16u);
  EXPECT_FLOAT_EQ(c.points[0].z(), 5000.0f);  // gamma 1: the stored value
  const std::pair<std::string, std::string> refused[] = {
      {png(4, 4, 0, 5000, chunk("gAMA", bigEndian(45455))), "gAMA"},
      {png(4, 4, 0, 5000, chunk("sRGB", std::string(1, '\0'))), "sRGB"},
      {png(4, 4, 0, 5000, chunk("tRNS", std::string(2, '\0'))), "tRNS"},
      {png(4, 4, 4, 5000), "without alpha"},
      {png(64, 64, 0, 7).substr(0, 50), "truncated"},
  };
  for (const auto& [bytes, why] : refused) {
    const std::string path = fileWith("refused.png", bytes);
    EXPECT_NE(refusal([&] { (void)readDepthPng(path, camera()); }).find(why), std::string::npos) << why;
  }
  // A chunk whose name holds a newline and whose length runs past the end: the message quotes it on one line.
  std::string cut = png(4, 4, 0, 5000);
  cut.replace(cut.find("IDAT") - 4, 8, bigEndian(100000) + "ID\nT");
  const std::string cut_path = fileWith("cut.png", cut);
  const std::string message = refusal([&] { (void)readDepthPng(cut_path, camera()); });
  EXPECT_NE(message.find("truncated (in its ID\\x0aT chunk)"), std::string::npos) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos);
  std::string large = png(4, 4, 0, 0);
  large.replace(16, 8, bigEndian(60000) + bigEndian(60000));  // the header claims 60000 x 60000
  const std::string path = fileWith("large.png", large);
  EXPECT_NE(refusal([&] { (void)readDepthPng(path, camera()); }).find("larger than"), std::string::npos);
}

namespace {

/// `bytes` with the first run equal to `was` replaced by `now`, and the checksum (zlib's CRC-32 of
/// all but the last four bytes, stored last) made right again: a crafted file, not a damaged one.
std::string recrafted(std::string bytes, const std::string& was, const std::string& now) {
  const std::size_t at = bytes.find(was);
  EXPECT_NE(at, std::string::npos);
  if (at == std::string::npos) return bytes;
  bytes.replace(at, now.size(), now);
  const std::size_t body = bytes.size() - 4;
  const auto crc = static_cast<std::uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(bytes.data()), uInt(body)));
  std::memcpy(bytes.data() + body, &crc, 4);
  return bytes;
}

template <class T>
std::string bytesOf(const T* values, std::size_t count) {
  return {reinterpret_cast<const char*>(values), count * sizeof(T)};
}

}  // namespace

// A database whose checksum is right but whose model is not one training makes (a NaN sample
// radius, a zero normal, a NaN point) is refused on loading, not loaded to find nothing.
TEST(HostileInput, DatabaseWithAnImpossibleModelIsRefused) {
  ModelParams params;
  params.num_points = 200;
  const OrientedModel model = prepareModel(builtinPart("cap"), params);
  const ModelDatabase db = ModelDatabase::build(model, defaultQuantization(model.diameter));
  const std::string path = test::tempPath("crafted.bpdb");
  db.save(path);
  const std::string good = test::readAll(path);
  const float nan = NAN, zeros[3] = {0, 0, 0};
  const float radius = db.model().sample_radius, tiny = 1e-40f;
  const std::uint64_t entries = db.entryCount(), wrapped = entries | (std::uint64_t{1} << 63), none = 0;
  const std::pair<std::string, std::string> crafted[] = {
      {recrafted(good, bytesOf(&radius, 1), bytesOf(&nan, 1)), "sample radius"},
      {recrafted(good, bytesOf(db.model().normals[0].data(), 3), bytesOf(zeros, 3)), "unit vector"},
      {recrafted(good, bytesOf(db.model().points[0].data(), 3), bytesOf(&nan, 1)), "not finite"},
      // an angle step of 1e-40 rad: more keys than any table holds, refused before a cast overflows
      {recrafted(good, bytesOf(&db.keySpace().params().d_angle, 1), bytesOf(&tiny, 1)), "too fine"},
      // 2^63 more entries than stored: the size check must not wrap around to a match
      {recrafted(good, bytesOf(&entries, 1), bytesOf(&wrapped, 1)), "does not match its header"},
      // no entries at all: nothing a detection could vote with
      {recrafted(good, bytesOf(&entries, 1), bytesOf(&none, 1)), "no point-pair features"},
  };
  for (const auto& [bytes, why] : crafted) {
    test::writeAll(path, bytes);
    const std::string m = refusal([&] { (void)ModelDatabase::load(path); });
    EXPECT_NE(m.find(why), std::string::npos) << why << ": " << m;
  }
  test::writeAll(path, good);
  EXPECT_NO_THROW((void)ModelDatabase::load(path));
}
