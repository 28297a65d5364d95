// Poisson-disk sampling of meshes and clouds (thesis 6.2).
#include <binpose/sampling.hpp>

#include <binpose/geometry.hpp>

#include <binpose/kdtree.hpp>

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <numeric>

namespace binpose {
namespace {

double triangleArea(const Mesh& mesh, const Eigen::Vector3i& f) {
  const Vec3& a = mesh.vertices[f[0]];
  return 0.5 * static_cast<double>((mesh.vertices[f[1]] - a).cross(mesh.vertices[f[2]] - a).norm());
}

std::vector<std::uint32_t> shuffledOrder(std::size_t n, std::uint64_t seed) {
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  Rng rng(seed);
  for (std::size_t i = n; i > 1; --i) std::swap(order[i - 1], order[rng.below(i)]);  // Fisher-Yates
  return order;
}

std::vector<std::uint32_t> select(const Points& candidates, const KdTree& tree,
                                  const std::vector<std::uint32_t>& order, float radius) {
  std::vector<char> blocked(candidates.size(), 0);
  std::vector<std::uint32_t> kept;
  std::vector<std::pair<std::uint32_t, float>> near;
  for (const std::uint32_t i : order) {
    if (blocked[i]) continue;
    kept.push_back(i);
    tree.radius(candidates[i], radius, near);
    for (const auto& [j, d2] : near)
      if (d2 < radius * radius) blocked[j] = 1;  // strictly closer than the radius
  }
  std::sort(kept.begin(), kept.end());
  return kept;
}

}  // namespace

double meshArea(const Mesh& mesh) {
  double area = 0;
  for (const auto& f : mesh.faces) area += triangleArea(mesh, f);
  return area;
}

std::vector<SurfacePoint> sampleSurfaceUniform(const Mesh& mesh, std::size_t count, std::uint64_t seed) {
  std::vector<double> cumulative(mesh.faces.size());
  double total = 0;
  for (std::size_t i = 0; i < mesh.faces.size(); ++i) cumulative[i] = (total += triangleArea(mesh, mesh.faces[i]));
  if (!(total > 0)) throw Error("mesh has zero surface area");
  Rng rng(seed);
  std::vector<SurfacePoint> samples(count);
  for (SurfacePoint& s : samples) {
    const double pick = rng.uniform() * total;
    s.face = static_cast<int>(std::min<std::size_t>(
        std::upper_bound(cumulative.begin(), cumulative.end(), pick) - cumulative.begin(), mesh.faces.size() - 1));
    double u = rng.uniform(), v = rng.uniform();
    if (u + v > 1.0) { u = 1.0 - u; v = 1.0 - v; }  // fold the square onto the triangle
    s.weights = Eigen::Vector3f(float(1.0 - u - v), float(u), float(v));
    const auto& f = mesh.faces[s.face];
    s.point = s.weights[0] * mesh.vertices[f[0]] + s.weights[1] * mesh.vertices[f[1]] + s.weights[2] * mesh.vertices[f[2]];
  }
  return samples;
}

std::vector<std::uint32_t> poissonDiskSelect(const Points& candidates, float radius, std::uint64_t seed) {
  if (!(radius >= 0)) throw Error(fmt::format("Poisson-disk radius must be >= 0, got {}", radius));
  const KdTree tree(candidates);
  return select(candidates, tree, shuffledOrder(candidates.size(), seed), radius);
}

std::vector<std::uint32_t> poissonDiskSelectCount(const Points& candidates, std::size_t target, std::uint64_t seed,
                                                  float* radius_out) {
  if (target == 0) throw Error("Poisson-disk sampling needs a target of at least one point");
  if (target >= candidates.size()) {  // nothing to thin out
    std::vector<std::uint32_t> all(candidates.size());
    std::iota(all.begin(), all.end(), 0u);
    if (radius_out) *radius_out = 0;
    return all;
  }
  const KdTree tree(candidates);
  const auto order = shuffledOrder(candidates.size(), seed);
  Vec3 lo, hi;
  bounds(candidates, lo, hi);
  float r_lo = 0, r_hi = (hi - lo).norm();  // count(r_lo) >= target > count(r_hi)
  std::vector<std::uint32_t> best = select(candidates, tree, order, r_hi);
  float best_r = r_hi;
  for (int it = 0; it < 40 && best.size() != target; ++it) {
    const float r = 0.5f * (r_lo + r_hi);
    auto kept = select(candidates, tree, order, r);
    const auto miss = [&](std::size_t n) { return n > target ? n - target : target - n; };
    if (miss(kept.size()) < miss(best.size())) { best = kept; best_r = r; }
    (kept.size() >= target ? r_lo : r_hi) = r;
    if (r_hi - r_lo < 1e-6f * r_hi) break;
  }
  if (radius_out) *radius_out = best_r;
  return best;
}

}  // namespace binpose
