// Depth images (16-bit PNG) and pinhole intrinsics (BOP camera.json / scene_camera.json).
#include "io_detail.hpp"
#include "pinhole_fit.hpp"

#include <binpose/io.hpp>

#include <algorithm>
#include <cmath>
#include <Eigen/Core>
#include <fstream>
#include <nlohmann/json.hpp>
#include <png.h>

namespace binpose {
namespace {

using detail::fail;
using nlohmann::json;

double number(const std::string& path, const json& j, const char* key) {
  if (!j.contains(key) || !j[key].is_number()) fail(path, fmt::format("intrinsics lack a numeric '{}'", key));
  return j[key].get<double>();
}

/// Names under which camera files give the 3 x 3 camera matrix: BOP's cam_K, ROS CameraInfo's K
/// (k in ROS 2), OpenCV's camera_matrix, Open3D's intrinsic_matrix (column-major).
constexpr const char* kMatrixKeys[] = {"cam_K", "K", "k", "camera_matrix", "intrinsic_matrix"};

const char* matrixKey(const json& j) {
  for (const char* key : kMatrixKeys)
    if (j.contains(key)) return key;
  return nullptr;
}

/// Whether a JSON object is one camera (not a scene_camera.json's map of them).
bool holdsCamera(const json& j) { return j.contains("fx") || matrixKey(j) != nullptr; }

/// The camera matrix [fx s cx; 0 fy cy; 0 0 1] from 9 numbers (row- or column-major: the layout
/// is told by where the zeros lie), 3 rows of 3, or OpenCV's {"rows": 3, "cols": 3, "data": [9]}.
Eigen::Matrix3d cameraMatrix(const std::string& path, const char* key, const json& value) {
  const json& data = value.is_object() && value.contains("data") ? value["data"] : value;
  std::vector<double> v;
  if (data.is_array())
    for (const json& row : data) {
      if (row.is_array())
        for (const json& x : row) v.push_back(x.is_number() ? x.get<double>() : NAN);
      else
        v.push_back(row.is_number() ? row.get<double>() : NAN);
    }
  if (v.size() != 9 || !std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); }))
    fail(path, fmt::format("{} must hold 9 numbers (a 3 x 3 camera matrix)", key));
  Eigen::Matrix3d K;
  K << v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8];
  if (K(1, 0) == 0 && K(2, 0) == 0 && K(2, 1) == 0 && (K(0, 2) != 0 || K(1, 2) != 0)) return K;
  if (K(0, 1) == 0 && K(0, 2) == 0 && K(1, 2) == 0) return K.transpose();  // column-major (Open3D)
  if (K(2, 0) == 0 && K(2, 1) == 0) return K;                              // principal point at the origin
  fail(path, fmt::format("{} is no camera matrix [fx 0 cx; 0 fy cy; 0 0 1]", key));
}

/// The organized cloud of a width x height depth image in its camera's frame (mm):
/// `depth_mm(pixel)` for each row-major pixel; one at 0, below it, NaN, or a point farther than
/// detail::kFarthestMm holds no measurement and is dropped.
template <typename DepthMm>
PointCloud depthCloud(int width, int height, const Intrinsics& k, DepthMm&& depth_mm) {
  PointCloud cloud;
  cloud.width = width;
  cloud.height = height;
  cloud.fx = float(k.fx);
  cloud.fy = float(k.fy);
  cloud.cx = float(k.cx);
  cloud.cy = float(k.cy);
  cloud.has_viewpoint = true;  // the camera frame
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      const double z = depth_mm(static_cast<std::size_t>(v) * width + u);
      if (!(z > 0 && z < detail::kFarthestMm)) continue;  // no measurement (NaN fails too)
      const double x = (u - k.cx) * z / k.fx, y = (v - k.cy) * z / k.fy;
      if (!(std::abs(x) < detail::kFarthestMm && std::abs(y) < detail::kFarthestMm)) continue;
      cloud.points.emplace_back(float(x), float(y), float(z));
      cloud.pixel.push_back(v * width + u);
    }
  return cloud;
}

/// The most pixels along an image side a camera file may claim.
constexpr double kMostImageSide = 65535;

int imageSide(const std::string& path, double v, const char* what) {
  if (!(v >= 1 && v <= kMostImageSide) || v != std::floor(v))
    fail(path, fmt::format("image {} must be a whole number in [1, {}], got {}", what, kMostImageSide, v));
  return static_cast<int>(v);
}

}  // namespace

void detail::checkIntrinsics(const std::string& path, const Intrinsics& k) {
  if (!(k.fx > 0) || !(k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy))
    fail(path, fmt::format("focal lengths must be positive (fx={}, fy={})", k.fx, k.fy));
  if (!std::isfinite(k.cx) || !std::isfinite(k.cy)) fail(path, "principal point is not finite");
  if (!(k.depth_scale > 0) || !std::isfinite(k.depth_scale))
    fail(path, fmt::format("depth_scale must be positive, got {}", k.depth_scale));
}

namespace {

/// The most pixels a depth image may have (a 12-megapixel sensor has a fifth of this).
constexpr std::size_t kMostPixels = std::size_t{1} << 26;
/// Deflate expands at most about 1032 times: a header claiming more pixels than the data can
/// hold is refused before they are allocated.
constexpr std::size_t kMostDeflateRatio = 1032;
/// A gAMA chunk's value for gamma 1 (linear): the only gamma under which libpng leaves the values.
constexpr std::uint32_t kLinearGamma = 100000;

/// A PNG's big-endian 32-bit field at p.
std::uint32_t bigEndian32(const char* p) {
  return static_cast<std::uint32_t>(detail::readScalar(p, detail::Scalar::UInt32, /*big_endian=*/true));
}

/// Walks the PNG's chunks: a 16-bit grey image without alpha (IHDR), no chunk under which
/// libpng would change the stored values (a gamma other than 1, sRGB, an ICC profile,
/// transparency; chromaticities do not touch grey), and a size the
/// image data can hold. The image's width and height.
std::pair<int, int> checkDepthPng(const std::string& path, const std::string& bytes) {
  static constexpr char kSignature[] = "\x89PNG\r\n\x1a\n";
  if (bytes.size() < 8 || bytes.compare(0, 8, kSignature, 8) != 0) fail(path, "not a PNG file");
  std::size_t pos = 8, image_data = 0;
  std::uint32_t width = 0, height = 0;
  while (pos + 12 <= bytes.size()) {
    const std::size_t length = bigEndian32(bytes.data() + pos);
    const std::string type = bytes.substr(pos + 4, 4);
    if (length > bytes.size() - pos - 12) fail(path, fmt::format("PNG is truncated (in its {} chunk)", type));
    const char* data = bytes.data() + pos + 8;
    if (type == "IHDR") {
      if (length < 13) fail(path, "PNG header chunk is too short");
      width = bigEndian32(data);
      height = bigEndian32(data + 4);
      if (data[8] != 16 || data[9] != 0) fail(path, "depth PNG must be 16-bit grayscale without alpha");
    } else if (type == "gAMA" && length >= 4 && bigEndian32(data) == kLinearGamma) {
      // gamma 1: linear, the values as stored (libpng's own linear output writes this)
    } else if (type == "gAMA" || type == "sRGB" || type == "iCCP" || type == "tRNS") {
      fail(path, fmt::format("depth PNG has a {} chunk, under which the stored depth would be changed on reading", type));
    } else if (type == "IDAT") {
      image_data += length;
    }
    pos += length + 12;
    if (type == "IEND") break;
  }
  if (width == 0 || height == 0) fail(path, "PNG has no image header or an empty image");
  const std::size_t pixels = std::size_t{width} * height;
  if (width > 65535 || height > 65535 || pixels > kMostPixels)
    fail(path, fmt::format("depth image of {} x {} pixels is larger than this reader allows", width, height));
  if (2 * pixels > kMostDeflateRatio * image_data + 1024)
    fail(path, fmt::format("PNG is truncated ({} bytes of image data for {} x {} pixels)", image_data, width, height));
  return {static_cast<int>(width), static_cast<int>(height)};
}

}  // namespace

Intrinsics readIntrinsics(const std::string& path, const std::string& image_id) {
  const std::string text = detail::readFileBytes(path);
  if (detail::jsonDepth(text) > detail::kMostJsonDepth) fail(path, "JSON nested too deeply to be a camera file");
  const json file = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (file.is_discarded() || !file.is_object()) fail(path, "not a JSON object");
  const json* entry = &file;
  if (!holdsCamera(file)) {  // scene_camera.json: {"<id>": {...}, ...}
    if (file.empty()) fail(path, "no camera entries");
    if (!image_id.empty() && !file.contains(image_id)) fail(path, fmt::format("no entry for image '{}'", image_id));
    entry = image_id.empty() ? &file.begin().value() : &file.at(image_id);
    if (!entry->is_object()) fail(path, "camera entry is not an object");
  }
  const json& j = *entry;
  Intrinsics k;
  if (const char* key = matrixKey(j)) {
    const Eigen::Matrix3d K = cameraMatrix(path, key, j[key]);
    k.fx = K(0, 0);
    k.fy = K(1, 1);
    k.cx = K(0, 2);
    k.cy = K(1, 2);
  } else {
    k.fx = number(path, j, "fx"); k.fy = number(path, j, "fy");
    k.cx = number(path, j, j.contains("ppx") ? "ppx" : "cx");  // ppx, ppy: RealSense's names
    k.cy = number(path, j, j.contains("ppy") ? "ppy" : "cy");
  }
  k.depth_scale = j.contains("depth_scale") ? number(path, j, "depth_scale") : 1.0;
  if (j.contains("width")) k.width = imageSide(path, number(path, j, "width"), "width");
  if (j.contains("height")) k.height = imageSide(path, number(path, j, "height"), "height");
  detail::checkIntrinsics(path, k);
  return k;
}

PointCloud depthToCloud(const std::vector<std::uint16_t>& depth, int width, int height, const Intrinsics& k) {
  return depthCloud(width, height, k, [&](std::size_t pixel) { return depth[pixel] * k.depth_scale; });
}

PointCloud depthToCloud(const std::vector<float>& depth, int width, int height, const Intrinsics& k) {
  return depthCloud(width, height, k, [&](std::size_t pixel) { return depth[pixel] * k.depth_scale; });
}

PointCloud pointMapToCloud(const Points& xyz, int width, int height) {
  PointCloud cloud;
  cloud.width = width;
  cloud.height = height;
  for (std::size_t p = 0; p < xyz.size(); ++p) {
    if (!isMeasured(xyz[p])) continue;  // NaN or the origin: a pixel without a measurement
    cloud.points.push_back(xyz[p]);
    cloud.pixel.push_back(static_cast<std::int32_t>(p));
  }
  fitPinhole(cloud);  // a point map in its camera's frame: its points on their pixels' rays
  return cloud;
}

PointCloud readDepthPng(const std::string& path, const Intrinsics& k) {
  detail::checkIntrinsics(path, k);
  const std::string bytes = detail::readFileBytes(path);
  checkDepthPng(path, bytes);  // before libpng reads or anything is allocated
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, bytes.data(), bytes.size()))
    fail(path, fmt::format("not a readable PNG ({})", image.message));
  if ((image.format & PNG_FORMAT_FLAG_COLOR) || !(image.format & PNG_FORMAT_FLAG_LINEAR)) {
    png_image_free(&image);
    fail(path, "depth PNG must be 16-bit grayscale");
  }
  image.format = PNG_FORMAT_LINEAR_Y;  // 16-bit grayscale, values untouched for a 16-bit file
  const int width = static_cast<int>(image.width), height = static_cast<int>(image.height);
  if (k.width > 0 && k.height > 0 && (k.width != width || k.height != height)) {
    png_image_free(&image);
    fail(path, fmt::format("image is {}x{} but the intrinsics say {}x{}", width, height, k.width, k.height));
  }
  std::vector<std::uint16_t> depth(static_cast<std::size_t>(width) * height);
  if (!png_image_finish_read(&image, nullptr, depth.data(), 0, nullptr))
    fail(path, fmt::format("corrupt PNG ({})", image.message));
  return depthToCloud(depth, width, height, k);
}

void writeDepthPng(const std::string& path, const std::vector<std::uint16_t>& depth, int width, int height) {
  if (depth.size() != static_cast<std::size_t>(width) * height) throw Error(fmt::format("{}: depth size mismatch", path));
  detail::writePng(path, width, height, PNG_FORMAT_LINEAR_Y, depth.data());
}

void detail::writePng(const std::string& path, int width, int height, std::uint32_t format, const void* pixels) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(width);
  image.height = static_cast<png_uint_32>(height);
  image.format = format;
  if (!png_image_write_to_file(&image, path.c_str(), 0, pixels, 0, nullptr))
    throw Error(fmt::format("{}: cannot write PNG ({})", path, image.message));
}

}  // namespace binpose
