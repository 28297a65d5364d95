#include <binpose/geometry.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <map>

namespace binpose {

float diameter(const Points& points) {
  const std::size_t n = points.size();
  const float best_sq = tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, n, 64), 0.0f,
      [&](const tbb::blocked_range<std::size_t>& range, float best) {
        for (std::size_t i = range.begin(); i != range.end(); ++i)
          for (std::size_t j = i + 1; j < n; ++j) best = std::max(best, (points[i] - points[j]).squaredNorm());
        return best;
      },
      [](float a, float b) { return std::max(a, b); });
  return std::sqrt(best_sq);
}

void sortByCell(std::span<const std::uint32_t> cell_of, std::size_t cells, std::vector<std::uint32_t>& offsets,
                std::vector<std::uint32_t>& order) {
  sortByCell(cell_of, cells, offsets, order, [](std::size_t, std::uint32_t) {});
}

bool bounds(const Points& points, Vec3& lo, Vec3& hi) {
  if (points.empty()) return false;
  lo = hi = points.front();
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return true;
}

float boundsDiagonal(const Points& points) {
  Vec3 lo, hi;
  return bounds(points, lo, hi) ? (hi - lo).norm() : 0.0f;
}

float medianOf(std::vector<float>& values) {
  const auto middle = values.begin() + static_cast<long>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

Eigen::Matrix3f lookingAlong(const Vec3& axis) {
  Eigen::Matrix3f to_view;
  to_view.row(2) = axis.transpose();
  to_view.row(0) = axis.unitOrthogonal().transpose();
  to_view.row(1) = to_view.row(2).cross(to_view.row(0));
  return to_view;
}

Vec3 surfaceCentroid(const Mesh& mesh) {
  Vec3 sum = Vec3::Zero();
  double area = 0;
  for (const auto& f : mesh.faces) {
    const Vec3 &a = mesh.vertices[f[0]], &b = mesh.vertices[f[1]], &c = mesh.vertices[f[2]];
    const float w = 0.5f * (b - a).cross(c - a).norm();
    sum += w * (a + b + c) / 3.0f;
    area += w;
  }
  return area > 0 ? Vec3(sum / static_cast<float>(area)) : Vec3::Zero();
}

void weldVertices(Mesh& mesh) {
  std::map<std::array<float, 3>, int> index;
  std::vector<int> remap(mesh.vertices.size());
  Points welded;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Vec3& v = mesh.vertices[i];
    const auto [it, inserted] = index.try_emplace({v.x(), v.y(), v.z()}, static_cast<int>(welded.size()));
    if (inserted) welded.push_back(v);
    remap[i] = it->second;
  }
  for (auto& f : mesh.faces) f = Eigen::Vector3i(remap[f[0]], remap[f[1]], remap[f[2]]);
  mesh.vertices = std::move(welded);
}

}  // namespace binpose
