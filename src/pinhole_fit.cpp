// A pinhole fitted to an organized cloud's points and pixels.
#include "pinhole_fit.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

namespace binpose {
namespace {

/// Farthest a point's projection may lie from its pixel, px: a pinhole's own points, rounded to
/// float, lie within 0.0002 px of theirs (PCL's milk frame at f = 525).
constexpr double kMostResidual = 0.01;
/// Fewest points the fit rests on.
constexpr std::size_t kLeastPoints = 16;
/// Gaps between a lattice's values that are one value rounded (float x / z: about 1e-7) and not
/// the step between two (a 10 000 px focal length's: 1e-4).
constexpr double kSameValue = 1e-5;
/// A lattice's image: at most this many pixels a point, and this many a side.
constexpr double kMostPixelsPerPoint = 64.0;
constexpr long kMostSide = 16384;
/// Values the lattice's step is read from.
constexpr std::size_t kStepSample = 4096;

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

/// The lattice the values t lie on, t = (k - c) / f for whole k from 0: f and c, and each value's
/// k. The step is read from an even sample of the values (a 640-column image's columns are nearly
/// all among 4096 of its points), the lattice checked on every value.
bool latticeOf(const std::vector<double>& t, double& f, double& c, std::vector<long>& k) {
  std::vector<double> sample;
  const std::size_t step = std::max<std::size_t>(1, t.size() / kStepSample);
  for (std::size_t i = 0; i < t.size(); i += step) sample.push_back(t[i]);
  std::sort(sample.begin(), sample.end());
  std::vector<double> gaps;
  for (std::size_t i = 1; i < sample.size(); ++i)
    if (sample[i] - sample[i - 1] > kSameValue) gaps.push_back(sample[i] - sample[i - 1]);
  if (gaps.size() < kLeastPoints) return false;
  std::nth_element(gaps.begin(), gaps.begin() + long(gaps.size() / 2), gaps.end());
  f = 1.0 / gaps[gaps.size() / 2];
  const double phase = f * *std::min_element(t.begin(), t.end());  // the least value is lattice point 0
  k.resize(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    k[i] = std::lround(f * t[i] - phase);
    if (k[i] >= kMostSide) return false;
  }
  // The step and phase refined over every value (the sample's gap is one value's rounding off).
  const Line line = fitLine(t.size(), [&](std::size_t i) { return std::pair{t[i], double(k[i])}; });
  f = line.f, c = line.c;
  return f > 0 && line.worst <= kMostResidual;
}

/// Each point's image on the plane z = 1 (x / z and y / z, where a pinhole at the origin sees it);
/// false when a point is not in front of the origin.
bool imagePlane(const Points& points, std::vector<double>& tx, std::vector<double>& ty) {
  tx.resize(points.size()), ty.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3& p = points[i];
    if (!(p.z() > 0) || !p.allFinite()) return false;
    tx[i] = double(p.x()) / p.z(), ty[i] = double(p.y()) / p.z();
  }
  return true;
}

}  // namespace

bool fitPixelLattice(PointCloud& cloud) {
  const std::size_t n = cloud.size();
  std::vector<double> tx, ty;
  if (cloud.organized() || cloud.fx > 0 || n < kLeastPoints || !imagePlane(cloud.points, tx, ty)) return false;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::vector<long> u, v;
  if (!latticeOf(tx, fx, cx, u) || !latticeOf(ty, fy, cy, v)) return false;
  const long width = *std::max_element(u.begin(), u.end()) + 1, height = *std::max_element(v.begin(), v.end()) + 1;
  if (double(width) * double(height) > kMostPixelsPerPoint * double(n)) return false;
  std::vector<std::int64_t> pixel(n);
  for (std::size_t i = 0; i < n; ++i) pixel[i] = v[i] * width + u[i];
  std::vector<std::uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return pixel[a] < pixel[b]; });
  for (std::size_t i = 1; i < n; ++i)
    if (pixel[order[i]] == pixel[order[i - 1]]) return false;  // two points on one pixel: not one view
  PointCloud out;
  for (const std::uint32_t i : order) {
    out.points.push_back(cloud.points[i]);
    if (cloud.hasNormals()) out.normals.push_back(cloud.normals[i]);
    out.pixel.push_back(std::int32_t(pixel[i]));
  }
  out.width = int(width), out.height = int(height);
  out.fx = float(fx), out.fy = float(fy), out.cx = float(cx), out.cy = float(cy);
  out.viewpoint = Vec3::Zero();
  out.has_viewpoint = true;  // the camera's frame
  cloud = std::move(out);
  return true;
}

bool fitPinhole(PointCloud& cloud) {
  const std::size_t n = cloud.size();
  std::vector<double> tx, ty;
  if (!cloud.organized() || cloud.fx > 0 || cloud.pixel.size() != n || n < kLeastPoints || !imagePlane(cloud.points, tx, ty))
    return false;
  const auto width = static_cast<double>(cloud.width);
  const Line u = fitLine(n, [&](std::size_t i) { return std::pair{tx[i], std::fmod(double(cloud.pixel[i]), width)}; });
  const Line v = fitLine(n, [&](std::size_t i) { return std::pair{ty[i], std::floor(double(cloud.pixel[i]) / width)}; });
  if (!(u.f > 0 && v.f > 0 && u.worst <= kMostResidual && v.worst <= kMostResidual)) return false;
  cloud.fx = float(u.f), cloud.fy = float(v.f), cloud.cx = float(u.c), cloud.cy = float(v.c);
  return true;
}

}  // namespace binpose
