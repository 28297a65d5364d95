// Thesis-style synthetic scenes (7.4): random poses, random surface samples, random occlusion.
#include <binpose/thesis_scene.hpp>

#include <binpose/geometry.hpp>
#include <binpose/model.hpp>
#include <binpose/sampling.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace binpose {
namespace {

/// Angular cell of the viewer's z-buffer, in units of the copies' distance: about 1 mm there.
constexpr float kCellAtDistance = 1.0f;
/// A point this far behind the nearest one in its cell is hidden (mm).
constexpr float kHiddenBehind = 1.0f;

/// The points of `points` (with outward `normals`) the viewer at the origin sees: facing it,
/// and nearest in their cell of an angular z-buffer.
std::vector<std::uint32_t> seenFromOrigin(const Points& points, const Points& normals, float cell) {
  std::unordered_map<std::int64_t, float> nearest;
  auto key = [&](const Vec3& p) {
    const auto u = static_cast<std::int64_t>(std::floor(p.x() / p.z() / cell));
    const auto v = static_cast<std::int64_t>(std::floor(p.y() / p.z() / cell));
    return (u << 32) ^ (v & 0xffffffff);
  };
  std::vector<std::uint32_t> facing;
  for (std::uint32_t i = 0; i < points.size(); ++i)
    if (normals[i].dot(-points[i]) > 0) facing.push_back(i);
  for (const auto i : facing) {
    auto [it, added] = nearest.try_emplace(key(points[i]), points[i].norm());
    if (!added) it->second = std::min(it->second, points[i].norm());
  }
  std::vector<std::uint32_t> seen;
  for (const auto i : facing)
    if (points[i].norm() <= nearest.at(key(points[i])) + kHiddenBehind) seen.push_back(i);
  return seen;
}

/// The share `kept` of `which` on one side of a random line across the view through the copy.
std::vector<std::uint32_t> occluded(const Points& points, std::vector<std::uint32_t> which, float kept, Rng& rng) {
  const double a = 2.0 * M_PI * rng.uniform();
  const Vec3 across(float(std::cos(a)), float(std::sin(a)), 0.0f);
  std::sort(which.begin(), which.end(), [&](std::uint32_t i, std::uint32_t j) {
    return points[i].dot(across) < points[j].dot(across) || (points[i].dot(across) == points[j].dot(across) && i < j);
  });
  which.resize(static_cast<std::size_t>(std::lround(kept * float(which.size()))));
  return which;
}

}  // namespace

SimulatedScene simulateThesisScene(const Mesh& mesh, const ThesisSceneParams& p) {
  if (p.instances < 1 || !(p.density > 0) || !(p.distance > 0) || !(p.spacing >= 1) || !(p.min_kept > 0) ||
      !(p.max_kept >= p.min_kept) || p.max_kept > 1 || !(p.noise_sigma >= 0))
    throw Error("thesis scene parameters out of range (instances >= 1, density > 0, spacing >= 1, 0 < min_kept <= max_kept <= 1)");
  const float diameter = binpose::diameter(mesh.vertices);
  const auto per_copy = static_cast<std::size_t>(std::ceil(double(p.density) * meshArea(mesh)));
  const Points face_normals = faceNormals(mesh);
  const int side = static_cast<int>(std::ceil(std::sqrt(double(p.instances))));
  const float step = p.spacing * diameter;
  Rng rng(p.seed);
  SimulatedScene scene;
  scene.camera_from_world = Pose::Identity();
  for (int i = 0; i < p.instances; ++i) {
    Pose pose = Pose::Identity();
    pose.linear() = rng.rotation().toRotationMatrix();
    pose.translation() = Vec3(step * (float(i % side) - 0.5f * float(side - 1)), step * (float(i / side) - 0.5f * float(side - 1)), p.distance);
    Points points, normals;
    for (const SurfacePoint& s : sampleSurfaceUniform(mesh, per_copy, p.seed * 1000003u + std::uint64_t(i))) {
      points.push_back(pose * s.point);
      normals.push_back(pose.linear() * face_normals[std::size_t(s.face)]);
    }
    const auto seen = seenFromOrigin(points, normals, kCellAtDistance / p.distance);
    const float kept_share = p.min_kept + float(rng.uniform()) * (p.max_kept - p.min_kept);
    const auto kept = occluded(points, seen, kept_share, rng);
    for (const auto k : kept) {
      const Vec3 ray = points[k].normalized();
      scene.cloud.points.push_back(points[k] + ray * (p.noise_sigma * rng.gaussian()));
    }
    SimulatedInstance inst;
    inst.pose = pose;
    inst.visible_fraction = float(kept.size()) / float(per_copy);
    inst.visib_fract = seen.empty() ? 0.0f : float(kept.size()) / float(seen.size());
    inst.visible_pixels = static_cast<int>(kept.size());
    scene.instances.push_back(inst);
  }
  return scene;
}

}  // namespace binpose
