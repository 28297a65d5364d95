// Depth images (16-bit PNG) and pinhole intrinsics (BOP camera.json / scene_camera.json).
#include "io_detail.hpp"

#include <binpose/io.hpp>

#include <cmath>
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

void validate(const std::string& path, const Intrinsics& k) {
  if (!(k.fx > 0) || !(k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy))
    fail(path, fmt::format("focal lengths must be positive (fx={}, fy={})", k.fx, k.fy));
  if (!std::isfinite(k.cx) || !std::isfinite(k.cy)) fail(path, "principal point is not finite");
  if (!(k.depth_scale > 0) || !std::isfinite(k.depth_scale))
    fail(path, fmt::format("depth_scale must be positive, got {}", k.depth_scale));
}

}  // namespace

Intrinsics readIntrinsics(const std::string& path, const std::string& image_id) {
  const std::string text = detail::readFileBytes(path);
  json j = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object()) fail(path, "not a JSON object");
  Intrinsics k;
  if (!j.contains("fx") && !j.contains("cam_K")) {  // scene_camera.json: {"<id>": {...}, ...}
    if (j.empty()) fail(path, "no camera entries");
    if (!image_id.empty() && !j.contains(image_id)) fail(path, fmt::format("no entry for image '{}'", image_id));
    j = image_id.empty() ? j.begin().value() : j[image_id];
    if (!j.is_object()) fail(path, "camera entry is not an object");
  }
  if (j.contains("cam_K")) {
    const json& K = j["cam_K"];
    if (!K.is_array() || K.size() != 9) fail(path, "cam_K must hold 9 numbers");
    for (const auto& v : K) if (!v.is_number()) fail(path, "cam_K must hold 9 numbers");
    k.fx = K[0].get<double>(); k.cx = K[2].get<double>();
    k.fy = K[4].get<double>(); k.cy = K[5].get<double>();
  } else {
    k.fx = number(path, j, "fx"); k.fy = number(path, j, "fy");
    k.cx = number(path, j, "cx"); k.cy = number(path, j, "cy");
  }
  k.depth_scale = j.contains("depth_scale") ? number(path, j, "depth_scale") : 1.0;
  if (j.contains("width")) k.width = static_cast<int>(number(path, j, "width"));
  if (j.contains("height")) k.height = static_cast<int>(number(path, j, "height"));
  validate(path, k);
  return k;
}

PointCloud depthToCloud(const std::vector<std::uint16_t>& depth, int width, int height, const Intrinsics& k) {
  PointCloud cloud;
  cloud.width = width;
  cloud.height = height;
  cloud.fx = float(k.fx);
  cloud.fy = float(k.fy);
  cloud.cx = float(k.cx);
  cloud.cy = float(k.cy);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      const std::uint16_t raw = depth[static_cast<std::size_t>(v) * width + u];
      if (raw == 0) continue;  // no measurement
      const double z = raw * k.depth_scale;
      cloud.points.emplace_back(float((u - k.cx) * z / k.fx), float((v - k.cy) * z / k.fy), float(z));
      cloud.pixel.push_back(v * width + u);
    }
  return cloud;
}

PointCloud readDepthPng(const std::string& path, const Intrinsics& k) {
  validate(path, k);
  const std::string bytes = detail::readFileBytes(path);
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
