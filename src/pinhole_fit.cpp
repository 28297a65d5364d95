// A pinhole fitted to an organized cloud's points and pixels.
#include "pinhole_fit.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace binpose {
namespace {

/// Farthest a point's projection may lie from its pixel, px: a pinhole's own points, rounded to
/// float, lie within 0.0002 px of theirs (PCL's milk frame at f = 525).
constexpr double kMostResidual = 0.01;
/// Fewest points the fit rests on.
constexpr std::size_t kLeastPoints = 16;

/// Least-squares line pixel = f t + c over (t, pixel) pairs, with its largest residual.
struct Line {
  double f = 0, c = 0, worst = INFINITY;
};

template <typename Pairs>
Line fitLine(std::size_t n, Pairs pairs) {
  double st = 0, sp = 0, stt = 0, stp = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto [t, p] = pairs(i);
    st += t, sp += p, stt += t * t, stp += t * p;
  }
  Line line;
  const double count = double(n), det = count * stt - st * st;
  if (!(det > 0)) return line;
  line.f = (count * stp - st * sp) / det;
  line.c = (sp - line.f * st) / count;
  line.worst = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const auto [t, p] = pairs(i);
    line.worst = std::max(line.worst, std::abs(p - (line.f * t + line.c)));
  }
  return line;
}

}  // namespace

bool fitPinhole(PointCloud& cloud) {
  const std::size_t n = cloud.size();
  if (!cloud.organized() || cloud.fx > 0 || cloud.pixel.size() != n || n < kLeastPoints) return false;
  for (const Vec3& p : cloud.points)
    if (!(p.z() > 0) || !p.allFinite()) return false;
  const auto width = static_cast<double>(cloud.width);
  const Line u = fitLine(n, [&](std::size_t i) {
    return std::pair{double(cloud.points[i].x()) / cloud.points[i].z(), std::fmod(double(cloud.pixel[i]), width)};
  });
  const Line v = fitLine(n, [&](std::size_t i) {
    return std::pair{double(cloud.points[i].y()) / cloud.points[i].z(), std::floor(double(cloud.pixel[i]) / width)};
  });
  if (!(u.f > 0 && v.f > 0 && u.worst <= kMostResidual && v.worst <= kMostResidual)) return false;
  cloud.fx = float(u.f), cloud.fy = float(v.f), cloud.cx = float(u.c), cloud.cy = float(v.c);
  return true;
}

}  // namespace binpose
