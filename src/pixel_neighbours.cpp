// Nearest neighbours of a depth image's points from their pixel neighbours, proved exact.
#include <binpose/pixel_neighbours.hpp>

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <memory>
#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace binpose {
namespace {

/// Pixels each side of the query's in the first window searched (3 x 3) and in the largest
/// (9 x 9). On the bench's 16-part bins (k = 8) 27-35% of the points were answered from 3 x 3
/// pixels, 57-65% within 7 x 7 and 97.6-99.3% within 9 x 9 (the bin's walls, seen at a grazing
/// angle, need that much); the rest went to the grid.
constexpr int kHalfWindow = 1;
constexpr int kMaxHalfWindow = 4;
constexpr int kSpan = 2 * kMaxHalfWindow + 1;  // the largest window's side
constexpr std::size_t kMaxK = 32;  // more neighbours are left to the grid
/// Coordinates beyond a million kilometres (mm) make the index unusable: the squared distances
/// of the points it holds are then finite, and only empty pixels' are infinite.
constexpr float kFar = 1e12f;
/// A row of the largest window read as three runs of four floats (12 columns from its first):
/// the padding right of the image covers the three past its last.
constexpr int kRowFloats = 12;
constexpr int kPadLeft = kMaxHalfWindow, kPadRight = kRowFloats - kMaxHalfWindow - 1, kPadRows = kMaxHalfWindow;

}  // namespace

PixelNeighbours::PixelNeighbours(const PointCloud& cloud) : cloud_(cloud) {
  if (!cloud.organized() || !(cloud.fx > 0) || !(cloud.fy > 0) || cloud.pixel.size() != cloud.size()) return;
  const std::size_t pixels = std::size_t(cloud.width) * std::size_t(cloud.height);
  if (pixels > std::size_t(INT32_MAX) / 2) return;
  // The image with a margin of empty pixels all round (every window lies inside it), written
  // once, pixel by pixel, in row order: the points must come in their pixels' order, as the
  // readers of depth images and organized clouds give them.
  const std::size_t width = std::size_t(cloud.width), pitch = width + kPadLeft + kPadRight;
  const std::size_t padded = pitch * (std::size_t(cloud.height) + 2 * kPadRows);
  auto at = std::make_unique_for_overwrite<std::int32_t[]>(padded);
  auto x = std::make_unique_for_overwrite<float[]>(padded), y = std::make_unique_for_overwrite<float[]>(padded),
       z = std::make_unique_for_overwrite<float[]>(padded);
  auto empty = [&](std::size_t from, std::size_t to) {
    std::fill(at.get() + from, at.get() + to, -1);
    for (float* plane : {x.get(), y.get(), z.get()}) std::fill(plane + from, plane + to, INFINITY);
  };
  const std::size_t n = cloud.size();
  std::size_t next = 0;  // the next point
  empty(0, kPadRows * pitch + kPadLeft);
  for (std::size_t v = 0; v < std::size_t(cloud.height); ++v) {
    const std::size_t row = (v + kPadRows) * pitch + kPadLeft;  // the row's first pixel
    for (std::size_t u = 0; u < width; ++u) {
      const std::size_t o = row + u;
      if (next == n || std::size_t(cloud.pixel[next]) != v * width + u) {
        at[o] = -1;
        x[o] = y[o] = z[o] = INFINITY;
        continue;
      }
      const Vec3& p = cloud.points[next];
      if (!(p.cwiseAbs().maxCoeff() < kFar) || !(p.z() > 0)) return;  // not on its pixel's ray, or beyond any sensor's range
      at[o] = static_cast<std::int32_t>(next++);
      x[o] = p.x(), y[o] = p.y(), z[o] = p.z();
    }
    empty(row + width, row + width + kPadRight + kPadLeft);  // this row's right margin, the next's left
  }
  empty((std::size_t(cloud.height) + kPadRows) * pitch + kPadLeft, padded);
  if (next != n) return;  // a pixel outside the image, twice, or out of order
  pitch_ = static_cast<std::ptrdiff_t>(pitch);
  at_ = std::move(at);
  x_ = std::move(x), y_ = std::move(y), z_ = std::move(z);
}

float PixelNeighbours::reach(const Vec3& q, int pixels) const {
  // A point p seen through a pixel m columns right of q's has the image coordinate X / Z of q's
  // plus m / fx (pinhole), so it lies beyond the plane X = s Z, s = x_q + m / fx, from q. The
  // distance from q to that plane, Z_q (m / fx) / sqrt(1 + s^2), bounds |p - q| from below;
  // |s| <= |x_q| + m / fx covers the left side too, and rows likewise. It grows with m.
  const float dx = float(pixels) / cloud_.fx, dy = float(pixels) / cloud_.fy;
  const float x = std::abs(q.x() / q.z()) + dx, y = std::abs(q.y() / q.z()) + dy;
  return q.z() * std::min(dx / std::sqrt(1.0f + x * x), dy / std::sqrt(1.0f + y * y));
}

namespace {

/// A query's largest window in the padded planes: its pixels' points and their squared
/// distances from the query.
struct Window {
  const std::int32_t* at;  ///< the window's top left pixel's point (row-major, `pitch` a row)
  const float *x, *y, *z;  ///< the same pixel's coordinates
  std::ptrdiff_t pitch;
  Vec3 q;
  alignas(16) float d2[kSpan][kRowFloats];  ///< the rows' squared distances (+inf for none), each row as it is needed

  /// Row `row`'s squared distances as (p - q).squaredNorm() sums them, x^2 + (y^2 + z^2), four
  /// columns at a time.
  __attribute__((always_inline)) void distances(int row) {
    const std::ptrdiff_t r = row * pitch;
#if defined(__SSE2__)
    const __m128 qx = _mm_set1_ps(q.x()), qy = _mm_set1_ps(q.y()), qz = _mm_set1_ps(q.z());
    for (int c = 0; c < kRowFloats; c += 4) {
      const __m128 dx = _mm_sub_ps(_mm_loadu_ps(x + r + c), qx);
      const __m128 dy = _mm_sub_ps(_mm_loadu_ps(y + r + c), qy);
      const __m128 dz = _mm_sub_ps(_mm_loadu_ps(z + r + c), qz);
      _mm_store_ps(d2[row] + c, _mm_add_ps(_mm_mul_ps(dx, dx), _mm_add_ps(_mm_mul_ps(dy, dy), _mm_mul_ps(dz, dz))));
    }
#else
    for (int c = 0; c < kSpan; ++c) d2[row][c] = (Vec3(x[r + c], y[r + c], z[r + c]) - q).squaredNorm();
#endif
  }
  /// The columns (bits) of row `row` no farther than `most`.
  [[nodiscard]] unsigned within(int row, float most) const {
#if defined(__SSE2__)
    const __m128 bound = _mm_set1_ps(most);
    unsigned near = 0;
    for (int c = 0; c < kRowFloats; c += 4)
      near |= unsigned(_mm_movemask_ps(_mm_cmple_ps(_mm_load_ps(d2[row] + c), bound))) << c;
    return near;
#else
    unsigned near = 0;
    for (int c = 0; c < kSpan; ++c) near |= unsigned(d2[row][c] <= most) << c;
    return near;
#endif
  }
};

/// The k nearest so far as keys (squared distance's bits, index), ascending: a non-negative
/// float's bits order as the float, so the keys order as NearestK's pairs (distance, then
/// index). A key goes in by k min-max steps without a branch, new[j] = min(max(old[j - 1], key),
/// old[j]) from the top; with K (k known when compiled) they stay in registers. A point's 15-20
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

/// The k nearest of the window's points: the 3 x 3 pixels first (most of the surfaces facing the
/// sensor end there), then the 9 x 9. True with them written out when `proved(half, limit)`
/// for the window's half side and the k-th's squared distance.
template <std::size_t K, class Proved>
bool windowNearest(Window& w, std::size_t k, std::uint32_t* indices, float* sq_dists, Proved proved) {
  NearestKeys<K> best(k);
  // Offers the points of the columns `lanes` (bits) of a row that may be among the k nearest.
  auto offer = [&](int row, unsigned lanes) {
    // The largest float as the bound before there are k: empty pixels (+inf) are never offered.
    for (lanes &= w.within(row, std::min(best.limit(), FLT_MAX)); lanes != 0; lanes &= lanes - 1) {
      const int c = std::countr_zero(lanes);
      best.insert(w.d2[row][c], static_cast<std::uint32_t>(w.at[row * w.pitch + c]));
    }
  };
  constexpr int kTop = kMaxHalfWindow - kHalfWindow, kBottom = kMaxHalfWindow + kHalfWindow;
  constexpr unsigned kInner = ((1u << (2 * kHalfWindow + 1)) - 1) << kTop;
  constexpr unsigned kAll = (1u << kSpan) - 1;
  for (int row = kTop; row <= kBottom; ++row) {
    w.distances(row);
    offer(row, kInner);
  }
  if (!(best.full() && proved(kHalfWindow, best.limit()))) {
    for (int row = 0; row < kSpan; ++row) {
      const bool inner = row >= kTop && row <= kBottom;
      if (!inner) w.distances(row);
      offer(row, inner ? kAll & ~kInner : kAll);
    }
    if (!(best.full() && proved(kMaxHalfWindow, best.limit()))) return false;
  }
  best.write(indices, sq_dists);
  return true;
}

}  // namespace

bool PixelNeighbours::knn(std::uint32_t i, std::size_t k, std::uint32_t* indices, float* sq_dists) const {
  if (!at_ || k == 0 || k > kMaxK || i >= cloud_.size()) return false;
  const std::int32_t px = cloud_.pixel[i];
  // The largest window's top left pixel in the padded image.
  const std::ptrdiff_t first = std::ptrdiff_t(px / cloud_.width) * pitch_ + px % cloud_.width;
  Window w;  // its distances left unset until a row is needed
  w.at = at_.get() + first;
  w.x = x_.get() + first, w.y = y_.get() + first, w.z = z_.get() + first;
  w.pitch = pitch_;
  w.q = cloud_.points[i];
  // Each window's answer, when proved, is the whole cloud's k nearest, and so the largest
  // window's; the reach grows with the window, so the largest proves whatever a smaller one
  // would. Strictly inside the reach, with a margin for the points' rounding to float: every
  // point outside the window is then farther than the k-th, even at equal index.
  auto proved = [&](int half, float limit) {
    const float reach = 0.999f * this->reach(w.q, half + 1);
    return limit < reach * reach;
  };
  switch (k) {  // the neighbours of the normals (k_normals: 6 by default, 8 fast) and of a spacing
    case 2: return windowNearest<2>(w, k, indices, sq_dists, proved);
    case 6: return windowNearest<6>(w, k, indices, sq_dists, proved);
    case 8: return windowNearest<8>(w, k, indices, sq_dists, proved);
    default: return windowNearest<0>(w, k, indices, sq_dists, proved);
  }
}

}  // namespace binpose
