// Flying pixels found by their depth against their 8 neighbouring pixels.
#include "flying_pixels.hpp"

#include "noise.hpp"
#include <binpose/pixel_neighbours.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace binpose {
namespace {

/// Sigmas of noise a neighbour on the same surface may differ by: two noisy depths differ by
/// sqrt(2) sigma at one sigma, so 3 sigma is 2.1 of their sigmas (under 2 % on either side).
constexpr float kJumpSigmas = 3.0f;
/// A surface at 60 degrees from the line of sight steps by tan(60) pixel footprints a pixel.
constexpr float kSteepestSlope = 1.7320508f;
/// A flying pixel has fewer neighbours than this within the jump of its depth.
constexpr int kSameSurfaceNeighbours = 2;
/// Points judged per task, side by side.
constexpr std::size_t kPointsPerTask = 4096;

/// Whether the point of depth z, its 8 neighbours' depths in `around` (0: no point), lies between
/// two surfaces.
bool flying(float z, const float (&around)[8], float jump) {
  bool nearer = false, farther = false;
  int same = 0;
  for (const float d : around) {
    if (!(d > 0)) continue;
    nearer |= d < z - jump;
    farther |= d > z + jump;
    same += std::abs(d - z) <= jump;
  }
  return nearer && farther && same < kSameSurfaceNeighbours;
}

/// The scan's noise as prepareScan measures it, through its pixels (0 when they cannot say).
float pixelNoise(const PointCloud& scan, const PixelNeighbours& pixels, const StageSettings& p) {
  std::vector<std::uint32_t> every(scan.size());
  std::iota(every.begin(), every.end(), 0u);
  return estimateNoise(scan.points, every, pixelQuery(pixels), p.viewpoint, p.far_noise).sigma;
}

}  // namespace

std::vector<char> flyingPixels(const PointCloud& scan, float sigma) {
  const bool image = scan.organized() && scan.fx > 0 && scan.pixel.size() == scan.size() && sigma >= 0 && std::isfinite(sigma);
  if (!image) return {};
  const long width = scan.width, height = scan.height;
  std::vector<float> depth(static_cast<std::size_t>(width * height), 0.0f);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const std::int32_t px = scan.pixel[i];
    if (px < 0 || px >= width * height) return {};  // not an image's points after all
    depth[static_cast<std::size_t>(px)] = scan.points[i].z();
  }
  std::vector<char> out(scan.size(), 0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, scan.size(), kPointsPerTask), [&](const auto& range) {
    for (std::size_t i = range.begin(); i < range.end(); ++i) {
      const long u = scan.pixel[i] % width, v = scan.pixel[i] / width;
      float around[8];
      int k = 0;
      for (long dv = -1; dv <= 1; ++dv)
        for (long du = -1; du <= 1; ++du) {
          if (du == 0 && dv == 0) continue;
          const long x = u + du, y = v + dv;
          around[k++] = x < 0 || y < 0 || x >= width || y >= height ? 0.0f : depth[static_cast<std::size_t>(y * width + x)];
        }
      const float z = scan.points[i].z();
      out[i] = flying(z, around, kJumpSigmas * sigma + kSteepestSlope * z / scan.fx);
    }
  });
  return out;
}

std::optional<PointCloud> withoutFlyingPixels(const PointCloud& scan, const StageSettings& p) {
  if (!p.adapt_to_noise || !p.remove_flying_pixels) return std::nullopt;
  const PixelNeighbours pixels(scan);
  if (!pixels.usable()) return std::nullopt;
  const std::vector<char> flying = flyingPixels(scan, pixelNoise(scan, pixels, p));
  if (std::find(flying.begin(), flying.end(), 1) == flying.end()) return std::nullopt;
  PointCloud kept;
  kept.width = scan.width;
  kept.height = scan.height;
  kept.viewpoint = scan.viewpoint;
  kept.has_viewpoint = scan.has_viewpoint;
  kept.fx = scan.fx, kept.fy = scan.fy, kept.cx = scan.cx, kept.cy = scan.cy;
  const auto count = static_cast<std::size_t>(std::count(flying.begin(), flying.end(), 0));
  kept.points.reserve(count);
  kept.pixel.reserve(count);
  if (scan.hasNormals()) kept.normals.reserve(count);
  for (std::size_t i = 0; i < scan.size(); ++i) {
    if (flying[i]) continue;
    kept.points.push_back(scan.points[i]);
    if (scan.hasNormals()) kept.normals.push_back(scan.normals[i]);
    kept.pixel.push_back(scan.pixel[i]);
  }
  return kept;
}

}  // namespace binpose
