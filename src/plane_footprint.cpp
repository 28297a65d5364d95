// Where the scan shows a plane: its inliers' cells on it, and the holes between them.
#include <binpose/planes.hpp>

#include <algorithm>
#include <cmath>

namespace binpose {
namespace {

/// Cells of a footprint: at most about this many (a wide plane gets larger cells).
constexpr double kMaxFootprintCells = 1 << 22;

/// `from` with every cell within `radius` cells of one of `value` (a square window clipped to the
/// grid) set to it: a dilation of the `value` cells, separable into rows then columns, each by a
/// running count of `value` cells in the window.
std::vector<char> grown(const std::vector<char>& from, long cols, long rows, long radius, char value) {
  std::vector<char> across(from.size()), out(from.size());
  const auto pass = [&](const std::vector<char>& in, std::vector<char>& to, long count, long lines, long stride, long step) {
    for (long line = 0; line < lines; ++line) {
      const long first = line * stride;
      const auto at = [&](long k) { return static_cast<std::size_t>(first + k * step); };
      long in_window = 0;
      for (long k = 0; k < std::min(radius, count); ++k) in_window += in[at(k)] == value;
      for (long k = 0; k < count; ++k) {
        if (k + radius < count) in_window += in[at(k + radius)] == value;
        if (k - radius - 1 >= 0) in_window -= in[at(k - radius - 1)] == value;
        to[at(k)] = in_window > 0 ? value : in[at(k)];
      }
    }
  };
  pass(from, across, cols, rows, cols, 1);  // along each row
  pass(across, out, rows, cols, 1, cols);   // along each column
  return out;
}

/// Whether each cell along the lines (`count` cells, `lines` of them, as in grown) has a set
/// cell within `reach` on both sides (itself set: yes).
void bracketed(const std::vector<char>& on, std::vector<char>& out, long count, long lines, long stride, long step, long reach) {
  for (long line = 0; line < lines; ++line) {
    const long first = line * stride;
    const auto at = [&](long k) { return static_cast<std::size_t>(first + k * step); };
    long last = -reach - 1;  // the last set cell before k
    for (long k = 0; k < count; ++k) {
      if (on[at(k)] != 0) last = k;
      out[at(k)] = k - last <= reach;
    }
    last = count + reach;  // the next set cell after k
    for (long k = count - 1; k >= 0; --k) {
      if (on[at(k)] != 0) last = k;
      out[at(k)] = out[at(k)] && last - k <= reach;
    }
  }
}

/// The cells set in `on`, or with set cells within `reach` along all four directions of the
/// grid: on it, or in a hole of it up to `reach` cells wide.
std::vector<char> bridged(const std::vector<char>& on, long cols, long rows, long reach) {
  std::vector<char> across(on.size()), down(on.size()), out(on.size());
  bracketed(on, across, cols, rows, cols, 1, reach);
  bracketed(on, down, rows, cols, 1, cols, reach);
  for (std::size_t i = 0; i < on.size(); ++i) out[i] = across[i] && down[i];
  return out;
}

}  // namespace

PlaneFootprint::PlaneFootprint(const Points& points, std::span<const std::uint32_t> inliers, const Plane& plane, float cell,
                               float hole)
    : u_(plane.normal.unitOrthogonal()), v_(plane.normal.cross(u_)) {
  for (const auto i : inliers) {
    const float a = u_.dot(points[i]), b = v_.dot(points[i]);
    u0_ = std::min(u0_, a), u1_ = std::max(u1_, a), v0_ = std::min(v0_, b), v1_ = std::max(v1_, b);
  }
  if (!(u1_ >= u0_ && v1_ >= v0_) || !(cell > 0)) return;
  side_ = std::max(cell, static_cast<float>(std::sqrt(double(u1_ - u0_) * double(v1_ - v0_) / kMaxFootprintCells)));
  cols_ = static_cast<long>((u1_ - u0_) / side_) + 1, rows_ = static_cast<long>((v1_ - v0_) / side_) + 1;
  on_.assign(static_cast<std::size_t>(cols_ * rows_), 0);
  for (const auto i : inliers) on_[this->cell(points[i])] = 1;
  on_ = grown(grown(on_, cols_, rows_, 1, 1), cols_, rows_, 1, 0);  // closed: dilated, then eroded
  area_ = static_cast<float>(std::count(on_.begin(), on_.end(), char{1})) * side_ * side_;
  const auto reach = static_cast<long>(std::ceil(std::min(double(hole) / double(side_), double(std::max(cols_, rows_)))));
  covered_ = bridged(on_, cols_, rows_, reach);
}

std::size_t PlaneFootprint::cell(const Vec3& p) const {
  const auto x = std::clamp(static_cast<long>((u_.dot(p) - u0_) / side_), 0L, cols_ - 1);
  const auto y = std::clamp(static_cast<long>((v_.dot(p) - v0_) / side_), 0L, rows_ - 1);
  return static_cast<std::size_t>(y * cols_ + x);
}

}  // namespace binpose
