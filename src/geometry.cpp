#include <binpose/geometry.hpp>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>

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

bool bounds(const Points& points, Vec3& lo, Vec3& hi) {
  if (points.empty()) return false;
  lo = hi = points.front();
  for (const Vec3& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return true;
}

}  // namespace binpose
