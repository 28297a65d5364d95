// Uniform grid for short-range neighbour queries (normals, ICP, verification).
#include <binpose/point_grid.hpp>

#include <binpose/geometry.hpp>

#include "nearest_k.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace binpose {
namespace {

/// A query that found no point within its distance last time (ICP's model points hidden behind
/// other parts) is searched out to this many times the distance: the same answer, and a larger
/// clearance, which spares its next searches. On cap-16's ICP 1.5 left 39 000 of 59 000 such
/// searches (1.2% of the detection's instructions); 3 searched too far.
constexpr float kMissReach = 1.5f;

int clampCell(float v, int n) { return static_cast<int>(std::clamp(std::floor(v), 0.0f, static_cast<float>(n - 1))); }

/// Shrinks the box [lo, hi] to the bulk of the points: per axis, the 1st to 99th percentile of
/// a sample, widened by a tenth of that span. A stray point far away would otherwise stretch
/// every cell. Points outside the box go into its border cells; since clamping is monotone,
/// every point within r of a query still lies in the cells the query's box clamps to.
void robustBox(const Points& points, std::size_t finite, Vec3& lo, Vec3& hi) {
  if (finite < 1000) return;
  const std::size_t step = std::max<std::size_t>(1, points.size() / 4096);
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<float> v;
    for (std::size_t i = 0; i < points.size(); i += step)
      if (points[i].allFinite()) v.push_back(points[i][axis]);
    if (v.size() < 100) return;
    const auto at = [&](double share) {
      const auto k = static_cast<long>(share * double(v.size() - 1));
      std::nth_element(v.begin(), v.begin() + k, v.end());
      return v[static_cast<std::size_t>(k)];
    };
    const float a = at(0.01), b = at(0.99), margin = 0.1f * (b - a);
    lo[axis] = std::max(lo[axis], a - margin);
    hi[axis] = std::min(hi[axis], b + margin);
  }
}

}  // namespace

float pixelSpacing(const PointCloud& cloud) {
  if (!cloud.organized() || cloud.pixel.size() != cloud.size() || cloud.size() < 2) return 0.0f;
  const auto w = static_cast<std::int64_t>(cloud.width), pixels = w * cloud.height;
  // Each point's pixel is its index in the row-major image, and the cloud keeps the image's
  // order (depthToCloud, readPcd): a neighbour pixel's point is found by a binary search.
  if (!std::is_sorted(cloud.pixel.begin(), cloud.pixel.end())) return 0.0f;
  const auto pointAt = [&](std::int64_t px) -> const Vec3* {
    if (px < 0 || px >= pixels) return nullptr;
    const auto it = std::lower_bound(cloud.pixel.begin(), cloud.pixel.end(), static_cast<std::int32_t>(px));
    return it != cloud.pixel.end() && *it == px ? &cloud.points[static_cast<std::size_t>(it - cloud.pixel.begin())] : nullptr;
  };
  std::vector<float> spacing;
  const std::size_t step = std::max<std::size_t>(1, cloud.size() / 500);
  for (std::size_t s = 0; s < cloud.size(); s += step) {
    const Vec3& p = cloud.points[s];
    const std::int64_t px = cloud.pixel[s];
    float best = INFINITY;
    for (const std::int64_t n : {px % w > 0 ? px - 1 : -1, px % w + 1 < w ? px + 1 : -1, px - w, px + w})
      if (const Vec3* q = pointAt(n); q != nullptr && *q != p) best = std::min(best, (*q - p).squaredNorm());
    if (std::isfinite(best)) spacing.push_back(std::sqrt(best));
  }
  if (spacing.size() < 10) return 0.0f;
  return medianOf(spacing);
}

PointGrid::PointGrid(const Points& points, float cell) {
  if (cell > 0 && std::isfinite(cell)) {
    build(points, cell);
    return;
  }
  // A first grid on the box's scale, then cells of twice the median spacing of a sample.
  build(points, 0.0f);
  if (ids_.size() < 2) return;
  std::vector<float> spacing;
  const std::size_t step = std::max<std::size_t>(1, ids_.size() / 500);
  for (std::size_t s = 0; s < ids_.size(); s += step) {
    std::uint32_t idx[2];
    float d2[2];
    if (knn(pointAt(static_cast<std::uint32_t>(s)), 2, idx, d2) == 2 && d2[1] > 0) spacing.push_back(std::sqrt(d2[1]));
  }
  if (spacing.empty()) return;
  build(points, 2.0f * medianOf(spacing));
}

void PointGrid::build(const Points& points, float cell) {
  Vec3 lo = Vec3::Constant(INFINITY), hi = Vec3::Constant(-INFINITY);
  std::size_t finite = 0;
  for (const Vec3& p : points)
    if (p.allFinite()) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
      ++finite;
    }
  offsets_.assign(2, 0);
  ids_.clear();
  x_.clear();
  y_.clear();
  z_.clear();
  nx_ = ny_ = nz_ = 1;
  if (finite == 0) return;
  robustBox(points, finite, lo, hi);
  const Vec3 extent = (hi - lo).cwiseMax(Vec3::Constant(1e-6f));
  const double max_cells = std::max<double>(4.0 * double(finite), double(1 << 20));
  const double volume = double(extent.x()) * extent.y() * extent.z();
  if (!(cell > 0)) cell = static_cast<float>(2.0 * std::cbrt(volume / double(finite)));  // the first, coarse grid
  cell = std::max({cell, static_cast<float>(std::cbrt(volume / max_cells)), 1e-6f * extent.maxCoeff()});
  auto cellsAlong = [&](float e) { return static_cast<int>(std::min<double>(std::floor(e / cell) + 1, max_cells)); };
  for (;;) {  // a flat or thin box: the cube-root bound above can still leave too many cells
    nx_ = cellsAlong(extent.x());
    ny_ = cellsAlong(extent.y());
    nz_ = cellsAlong(extent.z());
    if (double(nx_) * ny_ * nz_ <= max_cells) break;
    cell *= 1.25f;
  }
  cell_ = cell;
  lo_ = lo;
  std::vector<std::uint32_t> cell_of(points.size(), kNoCell);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!points[i].allFinite()) continue;
    const Vec3 a = (points[i] - lo_) / cell_;
    cell_of[i] = static_cast<std::uint32_t>((std::size_t(clampCell(a.z(), nz_)) * ny_ + clampCell(a.y(), ny_)) * nx_ +
                                            clampCell(a.x(), nx_));
  }
  // The coordinates laid out cell by cell as the points are sorted (written as read: a gather
  // after the sort took a third of the grid's build).
  x_.assign(finite + kPad, 0.0f);
  y_.assign(finite + kPad, 0.0f);
  z_.assign(finite + kPad, 0.0f);
  sortByCell(cell_of, std::size_t(nx_) * std::size_t(ny_) * std::size_t(nz_), offsets_, ids_, [&](std::size_t i, std::uint32_t s) {
    x_[s] = points[i].x();
    y_[s] = points[i].y();
    z_[s] = points[i].z();
  });
}

PointGrid::Box PointGrid::boxAround(const Vec3& q, float radius) const {
#if defined(__SSE4_1__)
  // clampCell's steps on the three axes at once (the same divisions, floors and clamps): a
  // quarter of the instructions, on a path every query takes.
  const __m128 cell = _mm_set1_ps(cell_), r = _mm_set1_ps(radius / cell_), zero = _mm_setzero_ps();
  const __m128 a = _mm_div_ps(_mm_sub_ps(_mm_setr_ps(q.x(), q.y(), q.z(), 0.0f), _mm_setr_ps(lo_.x(), lo_.y(), lo_.z(), 0.0f)), cell);
  const __m128 last = _mm_setr_ps(float(nx_ - 1), float(ny_ - 1), float(nz_ - 1), 0.0f);
  const auto clamped = [&](__m128 v) { return _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(_mm_floor_ps(v), zero), last)); };
  alignas(16) int low[4], high[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(low), clamped(_mm_sub_ps(a, r)));
  _mm_store_si128(reinterpret_cast<__m128i*>(high), clamped(_mm_add_ps(a, r)));
  return {low[0], high[0], low[1], high[1], low[2], high[2]};
#else
  const Vec3 a = (q - lo_) / cell_;
  const float r = radius / cell_;
  return {clampCell(a.x() - r, nx_), clampCell(a.x() + r, nx_), clampCell(a.y() - r, ny_),
          clampCell(a.y() + r, ny_), clampCell(a.z() - r, nz_), clampCell(a.z() + r, nz_)};
#endif
}

float PointGrid::coveredDistance(const Vec3& q, const Box& b) const {
  // A face on the grid's border bounds nothing: its cells also hold every point beyond it.
  const auto side = [&](int axis, int first, int last, int n) {
    const float low = first == 0 ? INFINITY : q[axis] - (lo_[axis] + float(first) * cell_);
    const float high = last == n - 1 ? INFINITY : lo_[axis] + float(last + 1) * cell_ - q[axis];
    return std::min(low, high);
  };
  return std::max(0.0f, std::min({side(0, b.x0, b.x1, nx_), side(1, b.y0, b.y1, ny_), side(2, b.z0, b.z1, nz_)}));
}

template <class Row>
bool PointGrid::anyRow(const Box& b, Row&& row) const {
  for (int z = b.z0; z <= b.z1; ++z)
    for (int y = b.y0; y <= b.y1; ++y) {
      const std::size_t at = (std::size_t(z) * ny_ + y) * nx_;  // a row's cells are side by side
      if (row(offsets_[at + b.x0], offsets_[at + b.x1 + 1])) return true;
    }
  return false;
}

template <class Hit>
bool PointGrid::scan(std::uint32_t first, std::uint32_t end, const Vec3& q, float limit, Hit&& hit, float* seen) const {
#if defined(__SSE2__)
  // (p - q).squaredNorm() of an Eigen 3-vector sums x^2 + (y^2 + z^2): the same here, lane by lane.
  const __m128 qx = _mm_set1_ps(q.x()), qy = _mm_set1_ps(q.y()), qz = _mm_set1_ps(q.z()), most = _mm_set1_ps(limit);
  alignas(16) float d2[4];
  for (std::uint32_t s = first; s < end; s += 4) {
    const __m128 dx = _mm_sub_ps(_mm_loadu_ps(x_.data() + s), qx);
    const __m128 dy = _mm_sub_ps(_mm_loadu_ps(y_.data() + s), qy);
    const __m128 dz = _mm_sub_ps(_mm_loadu_ps(z_.data() + s), qz);
    const __m128 d = _mm_add_ps(_mm_mul_ps(dx, dx), _mm_add_ps(_mm_mul_ps(dy, dy), _mm_mul_ps(dz, dz)));
    const unsigned valid = end - s >= 4 ? 0xFu : (1u << (end - s)) - 1u;  // lanes past `end`: other rows' points, or padding
    unsigned near = static_cast<unsigned>(_mm_movemask_ps(_mm_cmple_ps(d, most))) & valid;
    if (near == 0 && seen == nullptr) continue;
    _mm_store_ps(d2, d);
    if (seen != nullptr)
      for (unsigned lanes = valid; lanes != 0; lanes &= lanes - 1) *seen = std::min(*seen, d2[std::countr_zero(lanes)]);
    for (; near != 0; near &= near - 1) {
      const auto lane = static_cast<std::uint32_t>(std::countr_zero(near));
      if (hit(s + lane, d2[lane])) return true;
    }
  }
  return false;
#else
  for (std::uint32_t s = first; s < end; ++s) {
    const float d2 = (pointAt(s) - q).squaredNorm();
    if (seen != nullptr) *seen = std::min(*seen, d2);
    if (d2 <= limit && hit(s, d2)) return true;
  }
  return false;
#endif
}

std::size_t PointGrid::knn(const Vec3& q, std::size_t k, std::uint32_t* indices, float* sq_dists) const {
  if (k == 0 || ids_.empty() || !q.allFinite()) return 0;
  k = std::min(k, ids_.size());
  // Boxes of growing radius; done once the k-th nearest lies no farther than the box's nearest
  // face (every point that close lies inside the box), or the box holds every cell.
  for (float radius = cell_;; radius *= 2.0f) {
    detail::NearestK best{k, 0, indices, sq_dists};
    const Box b = boxAround(q, radius);
    anyRow(b, [&](std::uint32_t first, std::uint32_t end) {
      return scan(first, end, q, INFINITY, [&](std::uint32_t s, float d2) {
        best.offer(d2, ids_[s]);
        return false;
      });
    });
    const float covered = coveredDistance(q, b);
    if ((best.count == k && sq_dists[k - 1] <= covered * covered) || covered == INFINITY) return best.count;
  }
}

bool PointGrid::searchBox(const Vec3& q, float radius, float limit, std::uint32_t& index, float& sq_dist) const {
  detail::NearestK best{1, 0, &index, &sq_dist};
  anyRow(boxAround(q, radius), [&](std::uint32_t first, std::uint32_t end) {
    return scan(first, end, q, limit, [&](std::uint32_t s, float d2) {
      best.offer(d2, ids_[s]);
      return false;
    });
  });
  return best.count == 1;
}

bool PointGrid::nearest(const Vec3& q, float max_distance, std::uint32_t& index, float& sq_dist) const {
  if (ids_.empty() || !q.allFinite() || !(max_distance >= 0)) return false;
  // Most queries (ICP's, the score's) have a neighbour within half a cell: the 1-2 cells per axis
  // around q settle them (a box of a whole cell's radius is 3 cells per axis, 27 in all). The
  // nearest found within a radius is the nearest of all, so each step gives the same answer.
  for (const float radius : {0.5f * cell_, cell_})
    if (max_distance > radius && searchBox(q, radius, radius * radius, index, sq_dist)) return true;
  return searchBox(q, max_distance, max_distance * max_distance, index, sq_dist);
}

bool PointGrid::nearest(const Vec3& q, float max_distance, std::uint32_t& index, float& sq_dist,
                        float& clearance) const {
  const bool missed_before = clearance > 0;
  clearance = 0;
  if (ids_.empty() || !q.allFinite() || !(max_distance >= 0)) return false;
  if (!missed_before)  // as nearest(); a query that found none last time likely finds none nearer
    for (const float radius : {0.5f * cell_, cell_})
      if (max_distance > radius && searchBox(q, radius, radius * radius, index, sq_dist)) return true;
  // The last box as searchBox, keeping the nearest point seen beyond the limit too. Kept apart
  // from searchBox: tracking it there (behind a pointer test) cost every other query, 0.1-0.2%
  // of detect's instructions on the 16-part bins.
  const Box b = boxAround(q, missed_before ? kMissReach * max_distance : max_distance);
  const float limit = max_distance * max_distance;
  detail::NearestK best{1, 0, &index, &sq_dist};
  float seen = INFINITY;
  anyRow(b, [&](std::uint32_t first, std::uint32_t end) {
    return scan(first, end, q, limit, [&](std::uint32_t s, float d2) {
      best.offer(d2, ids_[s]);
      return false;
    }, &seen);
  });
  if (best.count == 1) return true;
  clearance = std::min(std::sqrt(seen), coveredDistance(q, b));
  return false;
}

bool PointGrid::nearestWithin(const Vec3& q, float sq_limit, std::uint32_t& index, float& sq_dist) const {
  if (ids_.empty() || !q.allFinite() || !(sq_limit >= 0)) return false;
  // The box a little wider than the limit's root, so rounding leaves out no point at the limit.
  return searchBox(q, std::sqrt(sq_limit) * (1.0f + 1e-5f) + 1e-6f * cell_, sq_limit, index, sq_dist);
}

bool PointGrid::anyWithin(const Vec3& q, float max_distance) const {
  if (ids_.empty() || !q.allFinite() || !(max_distance >= 0)) return false;
  const float limit = max_distance * max_distance;
  const auto hit = [&](const Box& b) {
    return anyRow(b, [&](std::uint32_t first, std::uint32_t end) {
      return scan(first, end, q, limit, [](std::uint32_t, float) { return true; });
    });
  };
  // As nearest(): the cells around q first, where a point on a surface the scan sees finds one.
  return (max_distance > 0.5f * cell_ && hit(boxAround(q, 0.5f * cell_))) || hit(boxAround(q, max_distance));
}

void PointGrid::within(const Vec3& q, float radius, std::vector<std::uint32_t>& out) const {
  out.clear();
  if (ids_.empty() || !q.allFinite() || !(radius > 0)) return;
  // Strictly closer: d2 < r^2 is d2 <= the float just below it (none when r^2 rounds to 0).
  const float square = radius * radius;
  if (!(square > 0)) return;
  const float limit = std::nextafter(square, 0.0f);
  anyRow(boxAround(q, radius), [&](std::uint32_t first, std::uint32_t end) {
    return scan(first, end, q, limit, [&](std::uint32_t s, float) {
      out.push_back(ids_[s]);
      return false;
    });
  });
}

}  // namespace binpose
