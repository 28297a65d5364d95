#pragma once
// A synthetic depth-sensor view of model copies at known poses, for end-to-end tests: dense
// surface samples projected through a pinhole camera at the origin (looking along +z), one
// point per pixel (the nearest sample, so self- and mutual occlusion are real), Gaussian noise
// along the viewing ray.
#include <binpose/geometry.hpp>
#include <binpose/model.hpp>
#include <binpose/pose.hpp>
#include <binpose/sampling.hpp>

#include <cmath>
#include <unordered_map>

namespace binpose::test {

struct SyntheticView {
  double focal = 700;          ///< px; at 500 mm a pixel spans 0.71 mm
  double samples_per_mm2 = 32;
  float noise_sigma = 0.1f;    ///< mm, along the ray
  std::uint64_t seed = 1;
};

inline float gaussian(Rng& rng) {
  return float(std::sqrt(-2.0 * std::log(1.0 - rng.uniform())) * std::cos(2.0 * M_PI * rng.uniform()));
}

/// `keep(copy, point_in_camera)` may drop points (cropping).
template <typename Keep>
PointCloud renderCopies(const Mesh& mesh, const std::vector<Pose>& poses, const SyntheticView& view, Keep keep) {
  const auto count = static_cast<std::size_t>(meshArea(mesh) * view.samples_per_mm2);
  std::unordered_map<std::int64_t, std::pair<float, Vec3>> nearest;  // pixel -> (depth, point)
  for (std::size_t c = 0; c < poses.size(); ++c) {
    for (const auto& s : sampleSurfaceUniform(mesh, count, view.seed + c)) {
      const Vec3 p = poses[c] * s.point;
      if (p.z() <= 0 || !keep(c, p)) continue;
      const auto u = static_cast<std::int64_t>(std::floor(view.focal * p.x() / p.z()));
      const auto v = static_cast<std::int64_t>(std::floor(view.focal * p.y() / p.z()));
      const std::int64_t pixel = (u + 100000) * 200000 + (v + 100000);
      auto [it, inserted] = nearest.try_emplace(pixel, p.z(), p);
      if (!inserted && p.z() < it->second.first) it->second = {p.z(), p};
    }
  }
  std::vector<std::pair<std::int64_t, Vec3>> sorted;
  for (const auto& [pixel, hit] : nearest) sorted.emplace_back(pixel, hit.second);
  std::sort(sorted.begin(), sorted.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  Rng rng(view.seed ^ 0xABCDEFull);
  PointCloud cloud;
  for (const auto& [pixel, p] : sorted) cloud.points.push_back(p * (1.0f + view.noise_sigma * gaussian(rng) / p.norm()));
  return cloud;
}

inline Pose randomPose(Rng& rng, const Vec3& position) {
  const Eigen::Quaternionf q = Eigen::Quaternionf(gaussian(rng), gaussian(rng), gaussian(rng), gaussian(rng)).normalized();
  Pose pose = Pose::Identity();
  pose.linear() = q.toRotationMatrix();
  pose.translation() = position;
  return pose;
}

/// Poses on a 4 x 3 grid, 45 mm apart, over the bin's floor (world frame, mm), each turned by
/// its own random rotation and raised to lie 1 mm above the floor: copies side by side, some
/// touching.
inline std::vector<Pose> gridOfCopies(const OrientedModel& model, int count, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Pose> world;
  for (int i = 0; i < count; ++i) {
    const Vec3 at(-67.5f + 45.0f * float(i % 4), -45.0f + 45.0f * float(i / 4), 0.0f);
    Pose pose = test::randomPose(rng, at);
    float lowest = INFINITY;
    for (const Vec3& p : model.points) lowest = std::min(lowest, (pose * p).z());
    pose.translation().z() += -lowest + 1.0f;
    world.push_back(pose);
  }
  return world;
}

/// A depth image of `width` x `height` pixels through a pinhole of focal length `fx` (px) at the
/// image's centre, depth(u, v) in mm (0: no point), as an organized cloud in pixel order.
template <typename Depth>
PointCloud depthImage(int width, int height, float fx, Depth depth) {
  PointCloud cloud;
  cloud.width = width;
  cloud.height = height;
  cloud.fx = cloud.fy = fx;
  cloud.cx = 0.5f * static_cast<float>(width - 1);
  cloud.cy = 0.5f * static_cast<float>(height - 1);
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u)
      if (const float z = depth(u, v); z > 0) {
        cloud.points.push_back(Vec3((static_cast<float>(u) - cloud.cx) / fx * z, (static_cast<float>(v) - cloud.cy) / fx * z, z));
        cloud.pixel.push_back(v * width + u);
      }
  return cloud;
}

}  // namespace binpose::test
