// Scene preparation and redundant sub-groups (thesis 5.2.1-5.2.4).
#include <binpose/scene.hpp>

#include <binpose/geometry.hpp>
#include <binpose/normals.hpp>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <fmt/format.h>
#include <numeric>
#include <tbb/parallel_for.h>
#if defined(__SSE4_1__)
#include <immintrin.h>
#endif

namespace binpose {
namespace {

/// The key of p's cube of side `size`: 21 bits per axis, x first.
std::uint64_t cellKey(const Vec3& p, float size) {
  std::uint64_t key = 0;
  for (int k = 0; k < 3; ++k) {
    const auto c = static_cast<std::int64_t>(std::floor(p[k] / size)) + (1 << 20);  // 21 bits per axis
    key = (key << 21) | (static_cast<std::uint64_t>(c) & 0x1FFFFF);
  }
  return key;
}

/// Each point's voxel (cubes of side `voxel` at floor(p / voxel)) as a number from 0, given in
/// the order the voxels are first met in index order; returns how many voxels there are.
std::size_t voxelIds(const Points& points, float voxel, std::vector<std::uint32_t>& voxel_of) {
  constexpr std::uint32_t kNone = ~std::uint32_t{0};
  const std::size_t n = points.size();
  std::vector<std::array<int, 4>> cell(n);  // x, y, z (and a lane unused)
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(INT32_MAX), hi = Eigen::Vector3i::Constant(INT32_MIN);
  bool small = true;  // coordinates within +-2^20 voxels: the keys of cellKey, and a dense index
  std::size_t first = 0;  // the first point of the scalar loop
#if defined(__SSE4_1__)
  // The three axes' divisions, floors and truncations at once: the same operations as below, in
  // two thirds of the time (ipd8-16's scan: 1.1 -> 0.75 ms). The fourth lane (the next point's
  // x) is left out of the bounds.
  const __m128 side = _mm_set1_ps(voxel), limit = _mm_set1_ps(float(1 << 20));
  const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7FFFFFFF));
  __m128 within = _mm_castsi128_ps(_mm_set1_epi32(-1));
  __m128i low = _mm_set1_epi32(INT32_MAX), high = _mm_set1_epi32(INT32_MIN);
  for (; first + 1 < n; ++first) {  // four floats from the point on: the last point is read apart
    const std::size_t i = first;
    const __m128 c = _mm_floor_ps(_mm_div_ps(_mm_loadu_ps(points[i].data()), side));
    within = _mm_and_ps(within, _mm_cmplt_ps(_mm_and_ps(c, magnitude), limit));
    const __m128i whole = _mm_cvttps_epi32(c);
    _mm_storeu_si128(reinterpret_cast<__m128i*>(cell[i].data()), whole);
    low = _mm_min_epi32(low, whole);
    high = _mm_max_epi32(high, whole);
  }
  alignas(16) std::int32_t l[4], h[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(l), low);
  _mm_store_si128(reinterpret_cast<__m128i*>(h), high);
  small = (_mm_movemask_ps(within) & 7) == 7;
  if (first > 0) {
    lo = Eigen::Vector3i(l[0], l[1], l[2]);
    hi = Eigen::Vector3i(h[0], h[1], h[2]);
  }
#endif
  for (std::size_t i = first; i < n; ++i) {
    const Vec3 c = (points[i] / voxel).array().floor();
    small &= c.cwiseAbs().maxCoeff() < float(1 << 20);
    const Eigen::Vector3i whole = c.cast<int>();
    cell[i] = {whole.x(), whole.y(), whole.z(), 0};
    lo = lo.cwiseMin(whole);
    hi = hi.cwiseMax(whole);
  }
  const Eigen::Vector3d size = (hi - lo).cast<double>().array() + 1.0;
  voxel_of.resize(n);
  std::uint32_t voxels = 0;
  if (small && size.prod() <= std::max(4.0 * double(n), double(1 << 20))) {  // a dense table over the box's voxels
    const auto nx = static_cast<std::size_t>(size.x()), ny = static_cast<std::size_t>(size.y());
    std::vector<std::uint32_t> id(static_cast<std::size_t>(size.prod()), kNone);
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3i c = Eigen::Vector3i(cell[i][0], cell[i][1], cell[i][2]) - lo;
      std::uint32_t& v = id[(std::size_t(c.z()) * ny + std::size_t(c.y())) * nx + std::size_t(c.x())];
      if (v == kNone) v = voxels++;
      voxel_of[i] = v;
    }
  } else {  // a sparse box (a stray point far away): sorted keys
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(n);
    for (std::size_t i = 0; i < n; ++i) keyed[i] = {cellKey(points[i], voxel), static_cast<std::uint32_t>(i)};
    std::sort(keyed.begin(), keyed.end());
    for (std::size_t i = 0; i < n; ++i) {
      if (i > 0 && keyed[i].first != keyed[i - 1].first) ++voxels;
      voxel_of[keyed[i].second] = voxels;
    }
    if (n > 0) ++voxels;
  }
  return voxels;
}

/// The points bucketed by x-y cells of side r from lo (floor((p - lo) / r) per axis; wider in a
/// scene of more than 2048 cells a side), each cell's in index order: a circle of radius r
/// touches at most 3 x 3 of them.
class XyCells {
 public:
  XyCells(const Points& points, const Vec3& lo, const Vec3& hi, float r)
      : side_(std::max(r, std::max(hi.x() - lo.x(), hi.y() - lo.y()) / 2048.0f)) {
    nx_ = cell(hi.x() - lo.x()) + 1;
    ny_ = cell(hi.y() - lo.y()) + 1;
    std::vector<std::uint32_t> cell_of(points.size());
    for (std::size_t i = 0; i < points.size(); ++i)
      cell_of[i] = static_cast<std::uint32_t>(cell(points[i].x() - lo.x()) * ny_ + cell(points[i].y() - lo.y()));
    sortByCell(cell_of, static_cast<std::size_t>(nx_ * ny_), offsets_, order_);
  }
  /// Calls visit(i) for each point i of the cells that overlap the x-y box [low, high] (relative to lo).
  template <class Visit>
  void inBox(const Vec3& low, const Vec3& high, Visit visit) const {
    const std::int64_t x0 = std::max<std::int64_t>(0, cell(low.x())), x1 = std::min(nx_ - 1, cell(high.x()));
    const std::int64_t y0 = std::max<std::int64_t>(0, cell(low.y())), y1 = std::min(ny_ - 1, cell(high.y()));
    for (std::int64_t cx = x0; cx <= x1; ++cx)
      for (std::int64_t cy = y0; cy <= y1; ++cy) {
        const auto c = static_cast<std::size_t>(cx * ny_ + cy);
        for (std::uint32_t k = offsets_[c]; k < offsets_[c + 1]; ++k) visit(order_[k]);
      }
  }

 private:
  [[nodiscard]] std::int64_t cell(float v) const { return static_cast<std::int64_t>(std::floor(v / side_)); }
  float side_;
  std::int64_t nx_ = 0, ny_ = 0;
  std::vector<std::uint32_t> offsets_, order_;
};

}  // namespace

std::vector<std::uint32_t> voxelSubsample(const Points& points, float voxel) {
  if (!(voxel > 0)) throw Error(fmt::format("voxel size must be positive, got {}", voxel));
  // Per voxel, the point nearest its points' centroid (the first of equals). Each voxel's sums and
  // comparisons run over its points in index order, as the points are read, with no sort.
  constexpr std::uint32_t kNone = ~std::uint32_t{0};
  std::vector<std::uint32_t> voxel_of;
  const std::size_t voxels = voxelIds(points, voxel, voxel_of);
  std::vector<Vec3> centroid(voxels, Vec3::Zero());
  std::vector<std::uint32_t> count(voxels, 0), best(voxels, kNone);
  for (std::size_t i = 0; i < points.size(); ++i) {
    centroid[voxel_of[i]] += points[i];
    ++count[voxel_of[i]];
  }
  for (std::size_t v = 0; v < voxels; ++v) centroid[v] /= static_cast<float>(count[v]);
  std::vector<float> best_d2(voxels);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::uint32_t v = voxel_of[i];
    const float d2 = (points[i] - centroid[v]).squaredNorm();
    if (best[v] == kNone || d2 < best_d2[v]) {
      best[v] = static_cast<std::uint32_t>(i);
      best_d2[v] = d2;
    }
  }
  std::vector<char> chosen(points.size(), 0);
  for (const std::uint32_t i : best) chosen[i] = 1;
  std::vector<std::uint32_t> kept;
  kept.reserve(voxels);
  for (std::size_t i = 0; i < points.size(); ++i)
    if (chosen[i]) kept.push_back(static_cast<std::uint32_t>(i));
  return kept;
}

std::vector<std::uint32_t> subsampleScene(const Points& scan, float rho_sub, Subsampling how, std::uint64_t seed) {
  if (scan.empty()) return {};
  const float spacing = 1.0f / std::sqrt(rho_sub);
  std::vector<std::uint32_t> chosen = voxelSubsample(scan, spacing);
  if (how == Subsampling::Random) {  // as many points, drawn at random (5.2.1)
    const std::size_t count = chosen.size();
    chosen.resize(scan.size());
    std::iota(chosen.begin(), chosen.end(), 0u);
    Rng rng(seed);
    for (std::size_t i = 0; i < count; ++i) std::swap(chosen[i], chosen[i + rng.below(scan.size() - i)]);
    chosen.resize(count);
    std::sort(chosen.begin(), chosen.end());
  }
  return chosen;
}

PreparedScene orientedScene(const Points& scan, std::span<const std::uint32_t> chosen, const Points& normals) {
  PreparedScene scene;
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    if (normals[i].squaredNorm() < 0.5f) continue;  // degenerate neighbourhood: skipped
    scene.points.push_back(scan[chosen[i]]);
    scene.normals.push_back(normals[i]);
    scene.scan_index.push_back(chosen[i]);
  }
  return scene;
}

PreparedScene prepareScene(const Points& scan, const PointGrid& scan_grid, std::span<const std::uint32_t> chosen,
                           int k, const Vec3& viewpoint, const PixelNeighbours* pixels) {
  return orientedScene(scan, chosen, estimateNormals(scan_grid, pixels, scan, chosen, k, viewpoint));
}

std::vector<std::vector<std::uint32_t>> makeSubGroups(const Points& points, float eta, float r, std::size_t min_size) {
  if (!(eta > 0) || !(r > 0)) throw Error(fmt::format("sub-groups need eta > 0 and r > 0, got {} and {}", eta, r));
  std::vector<std::vector<std::uint32_t>> groups;
  Vec3 lo, hi;
  if (!bounds(points, lo, hi)) return groups;
  const auto nx = static_cast<long>(std::floor((hi.x() - lo.x()) / eta)) + 1;
  const auto ny = static_cast<long>(std::floor((hi.y() - lo.y()) / eta)) + 1;
  if (nx * ny > 4'000'000) throw Error(fmt::format("eta {} mm gives {} sub-groups over the scene; use a larger eta", eta, nx * ny));
  const XyCells cells(points, lo, hi, r);
  // Each column of nodes on its own (in parallel), joined in column order.
  std::vector<std::vector<std::vector<std::uint32_t>>> columns(static_cast<std::size_t>(nx));
  tbb::parallel_for(tbb::blocked_range<long>(0, nx), [&](const tbb::blocked_range<long>& range) {
    std::vector<std::uint64_t> marks((points.size() + 63) / 64, 0);  // the members as bits, read out in index order
    for (long gx = range.begin(); gx != range.end(); ++gx)
      for (long gy = 0; gy < ny; ++gy) {
        const Vec3 node = lo + Vec3(float(gx) * eta, float(gy) * eta, 0.0f);
        std::size_t count = 0, first_word = marks.size(), last_word = 0;
        cells.inBox(node - lo + Vec3(-r, -r, 0.0f), node - lo + Vec3(r, r, 0.0f), [&](std::uint32_t i) {
          const Vec3& p = points[i];
          if ((p.x() - node.x()) * (p.x() - node.x()) + (p.y() - node.y()) * (p.y() - node.y()) > r * r) return;
          const std::size_t w = i / 64;
          count += (marks[w] >> (i % 64) & 1u) == 0;
          marks[w] |= std::uint64_t{1} << (i % 64);
          first_word = std::min(first_word, w);
          last_word = std::max(last_word, w);
        });
        if (count == 0) continue;
        std::vector<std::uint32_t> members;
        if (count >= min_size) members.reserve(count);
        for (std::size_t w = first_word; w <= last_word; ++w) {
          for (std::uint64_t bits = marks[w]; bits != 0 && count >= min_size; bits &= bits - 1)
            members.push_back(static_cast<std::uint32_t>(64 * w + std::size_t(std::countr_zero(bits))));
          marks[w] = 0;
        }
        if (count >= min_size) columns[static_cast<std::size_t>(gx)].push_back(std::move(members));
      }
  });
  for (auto& column : columns)
    for (auto& g : column) groups.push_back(std::move(g));
  if (groups.empty()) return groups;
  double mean = 0;
  for (const auto& g : groups) mean += static_cast<double>(g.size());
  mean /= static_cast<double>(groups.size());
  std::stable_sort(groups.begin(), groups.end(), [&](const auto& a, const auto& b) {
    return std::abs(static_cast<double>(a.size()) - mean) < std::abs(static_cast<double>(b.size()) - mean);
  });
  return groups;
}

}  // namespace binpose
