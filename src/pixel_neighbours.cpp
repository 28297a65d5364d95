// Nearest neighbours of a depth image's points from their pixel neighbours, proved exact.
#include <binpose/pixel_neighbours.hpp>

#include "nearest_k.hpp"

#include <algorithm>
#include <cmath>

namespace binpose {
namespace {

/// Pixels each side of the query's in the first window searched and in the largest; the window
/// grows a ring at a time. On the bench's 16-part bins (k = 8) 27-35% of the points were
/// answered from 3 x 3 pixels, 57-65% within 7 x 7 and 97.6-99.3% within 9 x 9 (the bin's walls,
/// seen at a grazing angle, need that much); the rest went to the grid.
constexpr int kHalfWindow = 1;
constexpr int kMaxHalfWindow = 4;

}  // namespace

PixelNeighbours::PixelNeighbours(const PointCloud& cloud) : cloud_(cloud) {
  if (!cloud.organized() || !(cloud.fx > 0) || !(cloud.fy > 0) || cloud.pixel.size() != cloud.size()) return;
  const std::size_t pixels = std::size_t(cloud.width) * std::size_t(cloud.height);
  if (pixels > std::size_t(INT32_MAX)) return;
  std::vector<std::int32_t> at(pixels, -1);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const std::int32_t px = cloud.pixel[i];
    if (px < 0 || std::size_t(px) >= pixels || at[std::size_t(px)] >= 0) return;  // not one pixel per point
    if (!cloud.points[i].allFinite() || !(cloud.points[i].z() > 0)) return;  // not on its pixel's ray
    at[std::size_t(px)] = static_cast<std::int32_t>(i);
  }
  at_ = std::move(at);
  // The largest window's pixels ring by ring (ring r: max(|dx|, |dy|) = r), nearest first
  // within a ring; the first window's rings (0 to kHalfWindow) as one.
  for (int dy = -kMaxHalfWindow; dy <= kMaxHalfWindow; ++dy)
    for (int dx = -kMaxHalfWindow; dx <= kMaxHalfWindow; ++dx) offsets_.emplace_back(dx, dy);
  const auto ring = [](const Eigen::Vector2i& o) { return std::max({std::abs(o.x()), std::abs(o.y()), kHalfWindow}); };
  std::stable_sort(offsets_.begin(), offsets_.end(), [&](const Eigen::Vector2i& a, const Eigen::Vector2i& b) {
    return ring(a) != ring(b) ? ring(a) < ring(b) : a.squaredNorm() < b.squaredNorm();
  });
  for (const Eigen::Vector2i& o : offsets_) steps_.push_back(std::ptrdiff_t(o.y()) * cloud.width + o.x());
  ring_end_.assign(std::size_t(kMaxHalfWindow) + 1, 0);
  for (const Eigen::Vector2i& o : offsets_) ++ring_end_[std::size_t(ring(o))];
  for (std::size_t r = 1; r < ring_end_.size(); ++r) ring_end_[r] += ring_end_[r - 1];
}

float PixelNeighbours::reach(const Vec3& q, int pixels) const {
  // A point p seen through a pixel m columns right of q's has the image coordinate X / Z of q's
  // plus m / fx (pinhole), so it lies beyond the plane X = s Z, s = x_q + m / fx, from q. The
  // distance from q to that plane, Z_q (m / fx) / sqrt(1 + s^2), bounds |p - q| from below;
  // |s| <= |x_q| + m / fx covers the left side too, and rows likewise.
  const float dx = float(pixels) / cloud_.fx, dy = float(pixels) / cloud_.fy;
  const float x = std::abs(q.x() / q.z()) + dx, y = std::abs(q.y() / q.z()) + dy;
  return q.z() * std::min(dx / std::sqrt(1.0f + x * x), dy / std::sqrt(1.0f + y * y));
}

bool PixelNeighbours::knn(std::uint32_t i, std::size_t k, std::uint32_t* indices, float* sq_dists) const {
  if (at_.empty() || k == 0 || i >= cloud_.size()) return false;
  const Vec3& q = cloud_.points[i];
  const int w = cloud_.width, h = cloud_.height;
  const int u = cloud_.pixel[i] % w, v = cloud_.pixel[i] / w;
  const bool inside = u >= kMaxHalfWindow && u + kMaxHalfWindow < w && v >= kMaxHalfWindow && v + kMaxHalfWindow < h;
  const std::int32_t* centre = at_.data() + cloud_.pixel[i];
  detail::NearestK best{k, 0, indices, sq_dists};
  auto visit = [&](std::size_t o) {
    if (const std::int32_t j = centre[steps_[o]]; j >= 0)
      best.offer((cloud_.points[std::size_t(j)] - q).squaredNorm(), static_cast<std::uint32_t>(j));
  };
  // Window by window, each one's pixels nearest first, so that the first few offers hold the k
  // nearest and the rest are turned away by one comparison.
  for (int half = kHalfWindow; half <= kMaxHalfWindow; ++half) {
    for (std::size_t o = ring_end_[std::size_t(half - 1)]; o < ring_end_[std::size_t(half)]; ++o)
      if (inside || (unsigned(u + offsets_[o].x()) < unsigned(w) && unsigned(v + offsets_[o].y()) < unsigned(h))) visit(o);
    if (best.count < k) continue;
    // Strictly inside the reach, with a margin for the points' rounding to float: every point
    // outside the window is then farther than the k-th, even at equal index order.
    const float reach = 0.999f * this->reach(q, half + 1);
    if (sq_dists[k - 1] < reach * reach) return true;
  }
  return false;
}

}  // namespace binpose
