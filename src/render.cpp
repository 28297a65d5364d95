// Pictures of detections: PNG from the sensor's view, coloured PLY.
#include <binpose/render.hpp>

#include "io_detail.hpp"

#include <binpose/geometry.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <png.h>

namespace binpose {
namespace {

using Rgb = std::array<std::uint8_t, 3>;
constexpr Rgb kPalette[] = {{230, 25, 75}, {60, 180, 75}, {255, 225, 25}, {0, 130, 200}, {245, 130, 48},
                            {145, 30, 180}, {70, 240, 240}, {240, 50, 230}, {210, 245, 60}, {250, 190, 212}};
Rgb colourOf(std::size_t rank) { return kPalette[rank % std::size(kPalette)]; }

/// 3 x 5 pixel digits, one row per 3 bits.
constexpr std::uint16_t kDigits[10] = {0x7B6F, 0x2C97, 0x73E7, 0x73CF, 0x5BC9, 0x79CF, 0x79EF, 0x7249, 0x7BEF, 0x7BCF};

/// A view from the viewpoint: the image plane is perpendicular to the scan's mean direction.
struct View {
  Eigen::Matrix3f rot;
  Vec3 origin;
  float u0 = 0, v0 = 0, scale = 1;
  int width = 0, height = 0;
  bool project(const Vec3& p, int& u, int& v, float& range) const {
    const Vec3 q = rot * (p - origin);
    if (q.z() <= 0) return false;
    range = q.norm();
    u = static_cast<int>((q.x() / q.z() - u0) * scale);
    v = static_cast<int>((q.y() / q.z() - v0) * scale);
    return u >= 0 && v >= 0 && u < width && v < height;
  }
};

View makeView(const Points& scan, const Vec3& viewpoint, int width) {
  View view;
  view.origin = viewpoint;
  Vec3 axis = Vec3::Zero();
  for (const Vec3& p : scan) axis += p - viewpoint;
  if (!normalizeSafe(axis)) axis = Vec3::UnitZ();
  // Keep the camera's own x axis when the view looks along +z (a depth camera's frame).
  const Vec3 x = std::abs(axis.dot(Vec3::UnitX())) < 0.9f ? Vec3(Vec3::UnitX() - axis * axis.x()).normalized() : axis.unitOrthogonal();
  view.rot.row(2) = axis.transpose();
  view.rot.row(0) = x.transpose();
  view.rot.row(1) = axis.cross(x).transpose();
  float u1 = -INFINITY, v1 = -INFINITY;
  view.u0 = view.v0 = INFINITY;
  for (const Vec3& p : scan) {
    const Vec3 q = view.rot * (p - viewpoint);
    if (q.z() <= 0) continue;
    view.u0 = std::min(view.u0, q.x() / q.z()); u1 = std::max(u1, q.x() / q.z());
    view.v0 = std::min(view.v0, q.y() / q.z()); v1 = std::max(v1, q.y() / q.z());
  }
  if (!(u1 > view.u0) || !(v1 > view.v0)) { view.u0 = view.v0 = -1; u1 = v1 = 1; }
  view.width = width;
  view.scale = float(width - 1) / (u1 - view.u0);
  view.height = std::clamp(static_cast<int>((v1 - view.v0) * view.scale) + 1, 1, 4 * width);
  return view;
}

}  // namespace

void renderDetections(const std::string& png_path, const PointCloud& scan, const std::vector<Detection>& detections,
                      const Points& model_points, const Points& model_normals, const Vec3& viewpoint, int width) {
  if (width < 16 || width > 8000) throw Error(fmt::format("render width must lie in [16, 8000], got {}", width));
  const View view = makeView(scan.points, viewpoint, width);
  const int W = view.width, H = view.height;
  std::vector<float> zbuf(static_cast<std::size_t>(W) * H, INFINITY);
  std::vector<Rgb> image(zbuf.size(), Rgb{0, 0, 0});
  float rmin = INFINITY, rmax = 0;
  for (const Vec3& p : scan.points) {
    const float r = (p - viewpoint).norm();
    rmin = std::min(rmin, r);
    rmax = std::max(rmax, r);
  }
  // splat size: about the scan's spacing on the image
  const int splat = std::clamp(static_cast<int>(std::ceil(std::sqrt(float(W) * float(H) / std::max<float>(1, float(scan.size()))))), 1, 4);
  auto put = [&](int u, int v, float range, const Rgb& c, bool depth_test) {
    for (int dv = 0; dv < splat; ++dv)
      for (int du = 0; du < splat; ++du) {
        const int x = u + du, y = v + dv;
        if (x >= W || y >= H) continue;
        const std::size_t i = static_cast<std::size_t>(y) * W + x;
        if (depth_test && range > zbuf[i]) continue;
        zbuf[i] = std::min(zbuf[i], range);
        image[i] = c;
      }
  };
  for (const Vec3& p : scan.points) {
    int u, v;
    float range;
    if (!view.project(p, u, v, range)) continue;
    const auto shade = static_cast<std::uint8_t>(40 + 190 * (1 - (range - rmin) / std::max(1e-6f, rmax - rmin)));
    put(u, v, range, {shade, shade, shade}, true);
  }
  const float tolerance = 0.01f * (rmax - rmin) + 1.0f;  // a model point on or in front of the scan is drawn
  for (std::size_t d = 0; d < detections.size(); ++d) {
    const Pose& pose = detections[d].pose;
    Vec3 centre = Vec3::Zero();
    for (std::size_t i = 0; i < model_points.size(); ++i) {
      const Vec3 p = pose * model_points[i];
      centre += p;
      if ((pose.linear() * model_normals[i]).dot(viewpoint - p) <= 0) continue;
      int u, v;
      float range;
      if (!view.project(p, u, v, range) || range > zbuf[static_cast<std::size_t>(v) * W + u] + tolerance) continue;
      put(u, v, range, colourOf(d), false);
    }
    int u, v;
    float range;
    if (!view.project(centre / float(model_points.size()), u, v, range)) continue;
    const std::string label = std::to_string(d + 1);  // rank, drawn 3x with a black border
    const int s = std::max(2, W / 200);
    for (std::size_t c = 0; c < label.size(); ++c)
      for (int row = 0; row < 5; ++row)
        for (int col = 0; col < 3; ++col) {
          if (!((kDigits[label[c] - '0'] >> (14 - (row * 3 + col))) & 1)) continue;
          for (int y = -1; y <= s; ++y)
            for (int x = -1; x <= s; ++x) {
              const int px = u + (static_cast<int>(c) * 4 + col) * s + x, py = v + row * s + y;
              if (px < 0 || py < 0 || px >= W || py >= H) continue;
              const bool border = x < 0 || y < 0 || x == s || y == s;
              Rgb& dst = image[static_cast<std::size_t>(py) * W + px];
              if (!border) dst = {255, 255, 255};
              else if (dst != Rgb{255, 255, 255}) dst = {0, 0, 0};
            }
        }
  }
  detail::writePng(png_path, W, H, PNG_FORMAT_RGB, image.data());
}

void exportDetectionsPly(const std::string& ply_path, const PointCloud& scan, const std::vector<Detection>& detections,
                         const Points& model_points) {
  std::ofstream out(ply_path, std::ios::binary);
  if (!out) throw Error(fmt::format("{}: cannot write", ply_path));
  const std::size_t n = scan.size() + detections.size() * model_points.size();
  out << "ply\nformat binary_little_endian 1.0\ncomment binpose detections: scan in grey, posed models in colour\n"
      << "element vertex " << n << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  auto write = [&](const Vec3& p, const Rgb& c) {
    out.write(reinterpret_cast<const char*>(p.data()), 3 * sizeof(float));
    out.write(reinterpret_cast<const char*>(c.data()), 3);
  };
  for (const Vec3& p : scan.points) write(p, {160, 160, 160});
  for (std::size_t d = 0; d < detections.size(); ++d)
    for (const Vec3& m : model_points) write(detections[d].pose * m, colourOf(d));
  if (!out) throw Error(fmt::format("{}: write failed", ply_path));
}

}  // namespace binpose
