// Nearest neighbours of a depth image's points from their pixel neighbours, proved exact.
#include <binpose/pixel_neighbours.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <memory>

namespace binpose {
namespace {

/// Pixels each side of the query's in the first window searched (3 x 3) and in the largest
/// (9 x 9). On the bench's 16-part bins (k = 8) 27-35% of the points were answered from 3 x 3
/// pixels, 57-65% within 7 x 7 and 97.6-99.3% within 9 x 9 (the bin's walls, seen at a grazing
/// angle, need that much); the rest went to the grid.
constexpr int kHalfWindow = 1;
constexpr int kMaxHalfWindow = 4;
constexpr std::size_t kMaxK = 32;  // more neighbours are left to the grid
constexpr int kPad = kMaxHalfWindow;  // empty pixels around the image: every window lies inside

}  // namespace

PixelNeighbours::PixelNeighbours(const PointCloud& cloud) : cloud_(cloud) {
  if (!cloud.organized() || !(cloud.fx > 0) || !(cloud.fy > 0) || cloud.pixel.size() != cloud.size()) return;
  const std::size_t pixels = std::size_t(cloud.width) * std::size_t(cloud.height);
  if (pixels > std::size_t(INT32_MAX) / 2 || cloud.size() > std::size_t(INT32_MAX)) return;
  // Each pixel of the image with its margin, in row order, gets the number of points before it:
  // a row's points between two columns are the cloud's between their counts. The points must
  // come in their pixels' order, as the readers of depth images and organized clouds give them.
  const std::size_t width = std::size_t(cloud.width), pitch = width + 2 * kPad;
  const std::size_t padded = pitch * (std::size_t(cloud.height) + 2 * kPad) + 1;  // and one past the last
  auto first = std::make_unique_for_overwrite<std::int32_t[]>(padded);
  const std::size_t n = cloud.size();
  std::size_t next = 0;  // the next point
  std::fill_n(first.get(), kPad * pitch + kPad, 0);
  for (std::size_t v = 0; v < std::size_t(cloud.height); ++v) {
    std::int32_t* row = first.get() + (v + kPad) * pitch + kPad;  // the row's first pixel
    const auto start = static_cast<std::int64_t>(v * width), end = start + static_cast<std::int64_t>(width);
    std::int64_t u = 0;  // the row's next pixel to write
    for (; next < n && cloud.pixel[next] < end; ++next) {  // the row's points
      const std::int64_t at = cloud.pixel[next] - start;
      if (at < u) return;  // a pixel twice, or out of order
      const Vec3& p = cloud.points[next];
      if (!p.allFinite() || !(p.z() > 0)) return;  // not on its pixel's ray
      for (; u <= at; ++u) row[u] = static_cast<std::int32_t>(next);
    }
    for (; u < std::int64_t(width) + 2 * kPad; ++u) row[u] = static_cast<std::int32_t>(next);  // its right margin, the next's left
  }
  std::fill(first.get() + (std::size_t(cloud.height) + kPad) * pitch + kPad, first.get() + padded, static_cast<std::int32_t>(next));
  if (next != n) return;  // a pixel outside the image, twice, or out of order
  pitch_ = static_cast<std::ptrdiff_t>(pitch);
  first_ = std::move(first);
}

float PixelNeighbours::reach(const Vec3& q, float pixels) const {
  // A point p seen through a pixel m columns right of q's has the image coordinate X / Z of q's
  // plus m / fx (pinhole), so it lies beyond the plane X = s Z, s = x_q + m / fx, from q. The
  // distance from q to that plane, Z_q (m / fx) / sqrt(1 + s^2), bounds |p - q| from below;
  // |s| <= |x_q| + m / fx covers the left side too, and rows likewise. It grows with m.
  const float dx = pixels / cloud_.fx, dy = pixels / cloud_.fy;
  const float x = std::abs(q.x() / q.z()) + dx, y = std::abs(q.y() / q.z()) + dy;
  return q.z() * std::min(dx / std::sqrt(1.0f + x * x), dy / std::sqrt(1.0f + y * y));
}

namespace {

/// The k nearest so far as keys (squared distance's bits, index), ascending: a non-negative
/// float's bits order as the float, so the keys order as NearestK's pairs (distance, then
/// index). A key goes in by k min-max steps without a branch, new[j] = min(max(old[j - 1], key),
/// old[j]) from the top; with K (k known when compiled) they stay in registers. A point's 10-20
/// insertions in random order were half of the search's time as NearestK's loop of shifts.
template <std::size_t K>
struct NearestKeys {
  static constexpr std::uint64_t kEmpty = ~std::uint64_t{0};
  std::size_t count;  // k when K is 0
  std::uint64_t keys[K == 0 ? kMaxK : K];

  explicit NearestKeys(std::size_t k) : count(k) { std::fill_n(keys, n(), kEmpty); }
  [[nodiscard]] std::size_t n() const { return K == 0 ? count : K; }
  [[nodiscard]] bool full() const { return keys[n() - 1] != kEmpty; }
  /// The k-th's squared distance (+inf before there are k).
  [[nodiscard]] float limit() const { return full() ? std::bit_cast<float>(std::uint32_t(keys[n() - 1] >> 32)) : INFINITY; }
  void insert(float d2, std::uint32_t index) {
    const std::uint64_t key = std::uint64_t(std::bit_cast<std::uint32_t>(d2)) << 32 | index;
    for (std::size_t j = n() - 1; j > 0; --j) keys[j] = std::min(std::max(keys[j - 1], key), keys[j]);
    keys[0] = std::min(keys[0], key);
  }
  void write(std::uint32_t* indices, float* sq_dists) const {
    for (std::size_t j = 0; j < n(); ++j) {
      indices[j] = std::uint32_t(keys[j]);
      sq_dists[j] = std::bit_cast<float>(std::uint32_t(keys[j] >> 32));
    }
  }
};

/// The k nearest of the points seen through the pixels around the query's: the 3 x 3 first (most
/// of the surfaces facing the sensor end there), then the 9 x 9. `points(dy, from, to)` gives the
/// cloud's range of the row dy from the query's, columns from..to from its. True with them written
/// out when `proved(half, limit)` for the window's half side and the k-th's squared distance
/// (+inf while fewer than k were seen: nothing to write out then).
template <std::size_t K, class Points_, class Proved>
bool windowNearest(const Points& cloud, const Vec3& q, std::size_t k, std::uint32_t* indices, float* sq_dists, Points_ points,
                   Proved proved) {
  NearestKeys<K> best(k);
  // Offers the points of a row's columns from..to (squared distances as PointGrid's).
  auto offer = [&](int dy, int from, int to) {
    const auto [begin, end] = points(dy, from, to);
    if constexpr (K == 1) {  // the nearest alone: a min per point, no test to mispredict (ICP's searches: 3.5 ms on cap-16)
      for (std::uint32_t j = begin; j < end; ++j) best.insert((cloud[j] - q).squaredNorm(), j);
      return;
    }
    const float most = best.limit();
    for (std::uint32_t j = begin; j < end; ++j)
      if (const float d2 = (cloud[j] - q).squaredNorm(); d2 <= most) best.insert(d2, j);
  };
  for (int dy = -kHalfWindow; dy <= kHalfWindow; ++dy) offer(dy, -kHalfWindow, kHalfWindow);
  if (!proved(kHalfWindow, best.limit())) {
    for (int dy = -kMaxHalfWindow; dy <= kMaxHalfWindow; ++dy) {
      if (std::abs(dy) > kHalfWindow) {
        offer(dy, -kMaxHalfWindow, kMaxHalfWindow);
        continue;
      }
      offer(dy, -kMaxHalfWindow, -kHalfWindow - 1);
      offer(dy, kHalfWindow + 1, kMaxHalfWindow);
    }
    if (!proved(kMaxHalfWindow, best.limit())) return false;
  }
  best.write(indices, sq_dists);
  return true;
}

/// windowNearest's `points` around the padded pixel table's entry `centre` (rows `pitch` apart).
auto rowsAround(const std::int32_t* centre, std::ptrdiff_t pitch) {
  return [centre, pitch](int dy, int from, int to) {
    const std::int32_t* row = centre + dy * pitch;
    return std::pair<std::uint32_t, std::uint32_t>(std::uint32_t(row[from]), std::uint32_t(row[to + 1]));
  };
}

}  // namespace

bool PixelNeighbours::knn(std::uint32_t i, std::size_t k, std::uint32_t* indices, float* sq_dists) const {
  if (!first_ || k == 0 || k > kMaxK || i >= cloud_.size()) return false;
  const std::int32_t px = cloud_.pixel[i];
  const auto points = rowsAround(first_.get() + (std::ptrdiff_t(px / cloud_.width) + kPad) * pitch_ + px % cloud_.width + kPad, pitch_);
  const Vec3& q = cloud_.points[i];
  // Each window's answer, when proved, is the whole cloud's k nearest, and so the largest
  // window's; the reach grows with the window, so the largest proves whatever a smaller one
  // would. Strictly inside the reach, with a margin for the points' rounding to float: every
  // point outside the window is then farther than the k-th, even at equal index (never proved
  // before k are seen: +inf).
  auto proved = [&](int half, float limit) {
    const float reach = 0.999f * this->reach(q, float(half + 1));
    return limit < reach * reach;
  };
  const Points& cloud = cloud_.points;
  switch (k) {  // the neighbours of the normals (k_normals: 6 by default, 8 fast) and of a spacing
    case 2: return windowNearest<2>(cloud, q, k, indices, sq_dists, points, proved);
    case 6: return windowNearest<6>(cloud, q, k, indices, sq_dists, points, proved);
    case 8: return windowNearest<8>(cloud, q, k, indices, sq_dists, points, proved);
    default: return windowNearest<0>(cloud, q, k, indices, sq_dists, points, proved);
  }
}

const std::int32_t* PixelNeighbours::centreOf(const Vec3& q) const {
  if (!first_ || !(q.z() > 0) || !q.allFinite()) return nullptr;
  const float u = std::nearbyint(cloud_.fx * (q.x() / q.z()) + cloud_.cx);
  const float v = std::nearbyint(cloud_.fy * (q.y() / q.z()) + cloud_.cy);
  if (!(u >= 0 && u < float(cloud_.width) && v >= 0 && v < float(cloud_.height))) return nullptr;
  return first_.get() + (std::ptrdiff_t(v) + kPad) * pitch_ + std::ptrdiff_t(u) + kPad;
}

PixelNeighbours::Proof PixelNeighbours::nearest(const Vec3& q, float sq_limit, std::uint32_t& index, float& sq_dist,
                                                float* clearance) const {
  const std::int32_t* centre = centreOf(q);
  if (centre == nullptr || !(sq_limit >= 0)) return Proof::kUnknown;
  // Every point outside a window lies farther than `reach` (q's image lies within half a pixel of
  // its pixel's centre, less a margin for the rounding of its projection): the window's nearest
  // within it is the cloud's, and with the limit within it and the window's nearest beyond the
  // limit, no point lies within the limit.
  Proof proof = Proof::kUnknown;
  float reach = 0, nearest_d2 = INFINITY;
  auto proved = [&](int half, float d2) {
    reach = 0.999f * this->reach(q, float(half) + 0.49f);
    nearest_d2 = d2;
    if (d2 < reach * reach) proof = d2 <= sq_limit ? Proof::kFound : Proof::kNone;
    else if (sq_limit < reach * reach) proof = Proof::kNone;
    return proof != Proof::kUnknown;
  };
  std::uint32_t found = 0;
  float found_d2 = 0;
  if (!windowNearest<1>(cloud_.points, q, 1, &found, &found_d2, rowsAround(centre, pitch_), proved)) return Proof::kUnknown;
  if (proof == Proof::kFound) {
    index = found;
    sq_dist = found_d2;
  } else if (clearance != nullptr) {
    *clearance = std::min(reach, std::sqrt(nearest_d2));
  }
  return proof;
}

}  // namespace binpose
