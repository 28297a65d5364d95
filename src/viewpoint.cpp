// The sensor origin of a scan whose file does not give it, from what a single view can show.
#include <binpose/viewpoint.hpp>

#include <binpose/geometry.hpp>
#include <binpose/point_grid.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace binpose {
namespace {

/// Points the hidden share is measured on: a steady share, a few milliseconds.
constexpr std::size_t kSamplePoints = 20000;
/// Range-image cells of this many sample spacings (at the median depth).
constexpr float kCellSpacings = 1.5f;
/// A point this many sample spacings behind its cell's nearest is hidden: a surface seen at 73
/// degrees to the line of sight spans about 5 spacings of depth over a cell.
constexpr float kHiddenSpacings = 5.0f;
/// The assumed origin is kept when it hides at most this share: a real sensor's scan shows a
/// few per cent of mixed pixels and points seen past an edge.
constexpr float kPlausibleHidden = 0.05f;
/// ... and otherwise replaced only by a viewpoint that hides at most this share of what it hides.
constexpr float kClearlyBetter = 0.5f;
/// The tilt search's first and last steps, degrees.
constexpr float kFirstTilt = 20.0f, kLastTilt = 5.0f;

struct Sample {
  Points points;
  float spacing = 0;
  Vec3 centre = Vec3::Zero();
  float extent = 0;  ///< bounding-box diagonal, mm
};

Sample sampleOf(const Points& points) {
  Sample s;
  const std::size_t step = std::max<std::size_t>(1, points.size() / kSamplePoints);
  for (std::size_t i = 0; i < points.size(); i += step)
    if (points[i].allFinite()) s.points.push_back(points[i]);
  if (s.points.size() < 3) return s;
  for (const Vec3& p : s.points) s.centre += p;
  s.centre /= static_cast<float>(s.points.size());
  s.extent = boundsDiagonal(s.points);
  if (!std::isfinite(s.extent)) return s;  // no spacing: nothing is guessed
  const PointGrid grid(s.points);
  std::vector<float> nearest;
  for (const Vec3& p : s.points) {
    std::uint32_t idx[2];
    float d2[2];
    if (grid.knn(p, 2, idx, d2) == 2 && d2[1] > 0) nearest.push_back(std::sqrt(d2[1]));
  }
  if (!nearest.empty()) s.spacing = medianOf(nearest);
  return s;
}

/// Share of the sample that `viewpoint` cannot see: behind it (along the mean line of sight),
/// or more than kHiddenSpacings behind the nearest point of its range-image cell.
float hiddenIn(const Sample& s, const Vec3& viewpoint) {
  Vec3 axis = s.centre - viewpoint;
  if (s.points.empty() || s.spacing <= 0 || !normalizeSafe(axis)) return 1.0f;
  const Eigen::Matrix3f to_view = lookingAlong(axis);
  std::vector<Vec3> seen;  // u, v (direction), range
  std::vector<float> depth;
  std::size_t behind = 0;
  for (const Vec3& p : s.points) {
    const Vec3 q = to_view * (p - viewpoint);
    if (q.z() <= 0) { ++behind; continue; }
    seen.emplace_back(q.x() / q.z(), q.y() / q.z(), q.norm());
    depth.push_back(q.z());
  }
  if (seen.empty()) return 1.0f;
  const double bin = kCellSpacings * s.spacing / medianOf(depth);
  // Cells as (x, y) keys, sorted: each run of a key is one line of sight.
  std::vector<std::pair<std::int64_t, float>> cells;
  cells.reserve(seen.size());
  for (const Vec3& c : seen) {
    const auto x = static_cast<std::int64_t>(std::clamp(std::floor(c.x() / bin), -1e9, 1e9));
    const auto y = static_cast<std::int64_t>(std::clamp(std::floor(c.y() / bin), -1e9, 1e9));
    cells.emplace_back(x * 4000000000LL + y, c.z());
  }
  std::sort(cells.begin(), cells.end());
  std::size_t hidden = behind;
  for (std::size_t a = 0, b = 0; a < cells.size(); a = b) {
    for (b = a; b < cells.size() && cells[b].first == cells[a].first; ++b) {}
    const float limit = cells[a].second + kHiddenSpacings * s.spacing;  // the run's least range first
    for (std::size_t i = a; i < b; ++i) hidden += cells[i].second > limit;
  }
  return static_cast<float>(hidden) / static_cast<float>(s.points.size());
}

/// The direction from the centre (unit) hiding the fewest points, from the principal axes, in
/// the upper half (z >= 0): a frame without a sensor is a world or robot frame, z up (REP 103;
/// HALCON's and SICK's world frames), and a bin's sensor looks down at it. From far away a single
/// view hides about as little seen from either side: the hidden share cannot tell up from down.
std::pair<Vec3, float> bestDirection(const Sample& s) {
  Eigen::Matrix3f cov = Eigen::Matrix3f::Zero();
  for (const Vec3& p : s.points) cov += (p - s.centre) * (p - s.centre).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> eig(cov);
  auto hiddenFrom = [&](const Vec3& d) { return hiddenIn(s, s.centre + s.extent * d); };
  std::pair<Vec3, float> best{Vec3::UnitZ(), 2.0f};
  for (int k = 0; k < 3; ++k) {
    Vec3 d = eig.eigenvectors().col(k).normalized();
    if (d.z() < 0) d = -d;
    if (const float h = hiddenFrom(d); h < best.second) best = {d, h};
  }
  // Tilt while it hides fewer, in halving steps.
  for (float step = kFirstTilt; step >= kLastTilt; step /= 2) {
    for (bool improved = true; improved;) {
      improved = false;
      const Vec3 a = best.first.unitOrthogonal(), b = best.first.cross(a);
      for (const Vec3& axis : {a, Vec3(-a), b, Vec3(-b)}) {
        const Vec3 d = Eigen::AngleAxisf(step * float(M_PI) / 180.0f, axis) * best.first;
        if (d.z() < 0) continue;
        if (const float h = hiddenFrom(d); h < best.second) {
          best = {d.normalized(), h};
          improved = true;
          break;
        }
      }
    }
  }
  return best;
}

}  // namespace

ViewpointGuess guessViewpoint(const Points& points, const Vec3& assumed) {
  ViewpointGuess g;
  g.viewpoint = assumed;
  const Sample s = sampleOf(points);
  g.hidden = g.assumed_hidden = hiddenIn(s, assumed);
  if (g.assumed_hidden <= kPlausibleHidden || !(s.spacing > 0) || !(s.extent > 0) || !std::isfinite(s.extent)) return g;
  const auto [direction, hidden] = bestDirection(s);
  if (hidden > kClearlyBetter * g.assumed_hidden) return g;
  g.viewpoint = s.centre + s.extent * direction;
  g.hidden = hidden;
  g.moved = true;
  return g;
}

}  // namespace binpose
