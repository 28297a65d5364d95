#pragma once
// Small geometric helpers and the project's deterministic random generator.
#include <binpose/types.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace binpose {

/// SplitMix64: a tiny, portable, seedable generator, so that the same seed gives the same
/// samples on every platform and standard library.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1).
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  /// Uniform integer in [0, n).
  std::uint64_t below(std::uint64_t n) { return static_cast<std::uint64_t>(uniform() * static_cast<double>(n)); }
  /// Standard normal (Box-Muller, from two uniforms).
  float gaussian() { return static_cast<float>(std::sqrt(-2.0 * std::log(1.0 - uniform())) * std::cos(2.0 * M_PI * uniform())); }
  /// A rotation uniform over SO(3): a normalised quaternion of four standard normals.
  Eigen::Quaternionf rotation() { return Eigen::Quaternionf(gaussian(), gaussian(), gaussian(), gaussian()).normalized(); }

 private:
  std::uint64_t state_;
};

/// The cell of an item left out of sortByCell.
constexpr std::uint32_t kNoCell = UINT32_MAX;

/// Counting sort of items 0..n-1 by cell (cell_of[i] < cells, or kNoCell to leave item i out):
/// `offsets` (cells + 1 of them) delimits each cell's run in `order`, a cell's items in
/// increasing order. O(n + cells): the scan's grid and voxel sub-sampling both bucket this way.
void sortByCell(std::span<const std::uint32_t> cell_of, std::size_t cells, std::vector<std::uint32_t>& offsets,
                std::vector<std::uint32_t>& order);

/// sortByCell, calling place(i, s) as item i is written to order[s]: the items' data laid out in
/// the sorted order in the same pass (a scatter as the items are read, not a gather after).
template <class Place>
void sortByCell(std::span<const std::uint32_t> cell_of, std::size_t cells, std::vector<std::uint32_t>& offsets,
                std::vector<std::uint32_t>& order, Place place) {
  // One array serves as counts, starts and write cursors (no copy of a cell array that can be
  // 4 MB): offsets[c + 2] counts cell c; summed, offsets[c + 1] is where c starts; each item
  // written moves it on, and at the end offsets[c] is where c starts, offsets[cells] the total.
  offsets.assign(cells + 2, 0);
  for (const auto c : cell_of)
    if (c != kNoCell) ++offsets[c + 2];
  for (std::size_t c = 2; c < cells + 2; ++c) offsets[c] += offsets[c - 1];
  order.resize(offsets[cells + 1]);
  for (std::size_t i = 0; i < cell_of.size(); ++i)
    if (cell_of[i] != kNoCell) {
      const std::uint32_t s = offsets[cell_of[i] + 1]++;
      order[s] = static_cast<std::uint32_t>(i);
      place(i, s);
    }
  offsets.pop_back();
}

/// Largest distance between two points (exact, O(n^2), parallel). 0 for fewer than two points.
float diameter(const Points& points);

/// Axis-aligned bounds; false when `points` is empty.
bool bounds(const Points& points, Vec3& lo, Vec3& hi);
/// The diagonal of the axis-aligned bounds (0 when `points` is empty).
float boundsDiagonal(const Points& points);

/// The median of `values` (the upper one of an even count), which it partly reorders; not empty.
float medianOf(std::vector<float>& values);

/// The rotation into a view frame whose z is the unit `axis` (a line of sight), x and y across it.
Eigen::Matrix3f lookingAlong(const Vec3& axis);

/// Area-weighted centroid of a mesh's surface (exact; on the axis of a body of revolution).
Vec3 surfaceCentroid(const Mesh& mesh);

/// Merges vertices at exactly the same position (STL repeats every corner), so that faces share
/// their corners and normals can be smoothed across edges.
void weldVertices(Mesh& mesh);

}  // namespace binpose
