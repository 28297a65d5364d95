// Large planes (bin floor, walls, table) found by one-point RANSAC and removed by patch.
#include <binpose/planes.hpp>

#include <binpose/geometry.hpp>
#include <binpose/point_grid.hpp>

#include "oriented_lanes.hpp"

#include <cmath>
#include <numeric>
#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>

namespace binpose {
namespace {

bool onPlane(const Vec3& p, const Vec3& n, const Plane& plane, float tolerance, float min_cos) {
  return plane.distance(p) <= tolerance && std::abs(plane.normal.dot(n)) >= min_cos;
}

/// Connected patches of `members` (links shorter than `link`), as lists of indices into points:
/// the components of a union-find over the pairs closer than `link`, each pair looked at once,
/// in cells a little wider than `link` (a linked pair lies in the same or neighbouring cells).
/// The distances are PointGrid's (x^2 + (y^2 + z^2) of the difference, strictly under link^2).
std::vector<std::vector<std::uint32_t>> patches(const Points& points, const std::vector<std::uint32_t>& members, float link) {
  const std::size_t n = members.size();
  std::vector<std::vector<std::uint32_t>> out;
  if (n == 0) return out;
  Vec3 lo = points[members[0]], hi = lo;
  for (const auto i : members) {
    lo = lo.cwiseMin(points[i]);
    hi = hi.cwiseMax(points[i]);
  }
  const float side = std::max(1.001f * link, 1e-6f * (hi - lo).maxCoeff());
  const Eigen::Array3d cells = ((hi - lo) / side).cast<double>().array().floor() + 1.0;
  if (cells.prod() > std::max(8.0 * double(n), double(1 << 20))) {  // a sparse box: the grid's flood fill
    Points sub;
    for (const auto i : members) sub.push_back(points[i]);
    const PointGrid grid(sub, link);
    std::vector<char> seen(n, 0);
    std::vector<std::uint32_t> stack, found;
    for (std::uint32_t s = 0; s < n; ++s) {
      if (seen[s]) continue;
      std::vector<std::uint32_t> patch;
      seen[s] = 1;
      stack.assign(1, s);
      while (!stack.empty()) {
        const std::uint32_t a = stack.back();
        stack.pop_back();
        patch.push_back(members[a]);
        grid.within(sub[a], link, found);
        for (const auto b : found)
          if (!seen[b]) {
            seen[b] = 1;
            stack.push_back(b);
          }
      }
      out.push_back(std::move(patch));
    }
    return out;
  }
  const auto nx = static_cast<std::size_t>(cells.x()), ny = static_cast<std::size_t>(cells.y()),
             nz = static_cast<std::size_t>(cells.z());
  std::vector<std::uint32_t> cell_of(n), offsets, order;
  auto cellOf = [&](const Vec3& p, std::size_t axis) {
    return std::min(static_cast<std::size_t>(std::max(0.0f, std::floor((p[axis] - lo[axis]) / side))),
                    (axis == 0 ? nx : axis == 1 ? ny : nz) - 1);
  };
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3& p = points[members[k]];
    cell_of[k] = static_cast<std::uint32_t>((cellOf(p, 2) * ny + cellOf(p, 1)) * nx + cellOf(p, 0));
  }
  sortByCell(cell_of, nx * ny * nz, offsets, order);
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto root = [&](std::uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  const float limit = link * link;
  auto linkCells = [&](std::size_t a, std::size_t b) {  // every pair of a point of cell a and one of cell b
    for (std::uint32_t s = offsets[a]; s < offsets[a + 1]; ++s)
      for (std::uint32_t t = a == b ? s + 1 : offsets[b]; t < offsets[b + 1]; ++t) {
        const Vec3 d = points[members[order[t]]] - points[members[order[s]]];
        if (d.x() * d.x() + (d.y() * d.y() + d.z() * d.z()) >= limit) continue;
        const std::uint32_t ra = root(order[s]), rb = root(order[t]);
        if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
      }
  };
  for (std::size_t z = 0; z < nz; ++z)
    for (std::size_t y = 0; y < ny; ++y)
      for (std::size_t x = 0; x < nx; ++x) {
        const std::size_t a = (z * ny + y) * nx + x;
        if (offsets[a] == offsets[a + 1]) continue;
        // The cell itself and its 13 neighbours that come after it in (z, y, x) order.
        for (int dz = 0; dz <= 1; ++dz)
          for (int dy = dz == 0 ? 0 : -1; dy <= 1; ++dy)
            for (int dx = dz == 0 && dy == 0 ? 0 : -1; dx <= 1; ++dx) {
              const std::ptrdiff_t bx = std::ptrdiff_t(x) + dx, by = std::ptrdiff_t(y) + dy, bz = std::ptrdiff_t(z) + dz;
              if (bx < 0 || by < 0 || bx >= std::ptrdiff_t(nx) || by >= std::ptrdiff_t(ny) || bz >= std::ptrdiff_t(nz)) continue;
              linkCells(a, (std::size_t(bz) * ny + std::size_t(by)) * nx + std::size_t(bx));
            }
      }
  std::vector<std::uint32_t> patch_of(n, ~std::uint32_t{0});
  for (std::uint32_t k = 0; k < n; ++k) {
    std::uint32_t& p = patch_of[root(k)];
    if (p == ~std::uint32_t{0}) {
      p = static_cast<std::uint32_t>(out.size());
      out.emplace_back();
    }
    out[p].push_back(members[k]);
  }
  return out;
}

/// How many probe points lie on `plane`: onPlane with the same sums in the same order, on SIMD
/// lanes (300 hypotheses a plane made this loop half of the plane search's time).
__attribute__((target_clones("avx2", "default")))
std::size_t countOnPlane(const detail::OrientedLanes& probe, const Plane& plane, float tolerance, float min_cos) {
  const float* x = probe.c[0].data();
  const float* y = probe.c[1].data();
  const float* z = probe.c[2].data();
  const float* nx = probe.c[3].data();
  const float* ny = probe.c[4].data();
  const float* nz = probe.c[5].data();
  const float a = plane.normal.x(), b = plane.normal.y(), c = plane.normal.z(), d = plane.d;
  std::uint32_t count = 0;
  for (std::size_t k = 0; k < probe.size; ++k) {
    const bool near = std::abs(a * x[k] + b * y[k] + c * z[k] - d) <= tolerance;
    const bool aligned = std::abs(a * nx[k] + b * ny[k] + c * nz[k]) >= min_cos;
    count += static_cast<std::uint32_t>(near & aligned);
  }
  return count;
}

}  // namespace

PlaneParams planeParams(const DetectionParams& params) {
  PlaneParams planes;
  planes.min_area = params.plane_min_area;
  planes.tolerance = params.plane_tolerance;
  planes.link = 2.5f / std::sqrt(params.rho_sub);  // neighbours on a plane are one sample spacing apart
  planes.seed = params.seed;
  return planes;
}

std::vector<char> largePlanes(const Points& points, const Points& normals, float density, const PlaneParams& params,
                              std::vector<Plane>* removed) {
  if (points.size() != normals.size()) throw Error("largePlanes: one normal per point needed");
  if (!(density > 0) || !(params.min_area > 0) || !(params.tolerance > 0) || !(params.link > 0))
    throw Error(fmt::format("plane removal needs positive density, area, tolerance and link, got {}, {}, {}, {}", density,
                            params.min_area, params.tolerance, params.link));
  std::vector<char> plane(points.size(), 0), tried(points.size(), 0);
  const auto min_count = static_cast<std::size_t>(std::ceil(params.min_area * density));
  const float min_cos = std::cos(params.max_angle);
  Rng rng(params.seed);
  std::vector<std::uint32_t> left, probe, inliers;
  detail::OrientedLanes probe_points;  // the points a RANSAC hypothesis is scored on
  std::vector<Plane> hypotheses;
  std::vector<std::size_t> counts;
  // A background plane's inliers split into patches (a flood fill, a third of the search's
  // time) while the next rounds look for planes: the next round's points do not depend on it
  // (every inlier is tried, whatever patch it falls in), and rounds' inliers are disjoint.
  struct Background {
    Plane plane;
    std::vector<std::uint32_t> inliers;
    bool taken = false;
  };
  std::vector<Background> background;
  background.reserve(static_cast<std::size_t>(std::max(0, params.max_planes)));  // no move under a running task
  tbb::task_group flood;
  for (int round = 0; round < params.max_planes; ++round) {
    left.clear();
    for (std::uint32_t i = 0; i < points.size(); ++i)
      if (!tried[i]) left.push_back(i);
    if (left.size() < min_count) break;
    // Hypotheses scored on an even sample of at most 1000 of the points left.
    probe.clear();
    const std::size_t step = std::max<std::size_t>(1, left.size() / 1000);
    for (std::size_t k = 0; k < left.size(); k += step) probe.push_back(left[k]);
    probe_points.assign(points, normals, probe.size(), [&](std::size_t k) { return probe[k]; });
    // The hypotheses drawn in turn, scored side by side, the first of the highest score kept.
    hypotheses.clear();
    for (int t = 0; t < params.trials; ++t) {
      const std::uint32_t s = left[rng.below(left.size())];
      hypotheses.push_back({normals[s], normals[s].dot(points[s])});
    }
    counts.resize(hypotheses.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, hypotheses.size(), 32), [&](const auto& range) {
      for (std::size_t t = range.begin(); t < range.end(); ++t)
        counts[t] = countOnPlane(probe_points, hypotheses[t], params.tolerance, min_cos);
    });
    std::size_t best_count = 0;
    Plane best;
    for (std::size_t t = 0; t < hypotheses.size(); ++t)
      if (counts[t] > best_count) {
        best_count = counts[t];
        best = hypotheses[t];
      }
    inliers.clear();
    for (const auto i : left)
      if (onPlane(points[i], normals[i], best, params.tolerance, min_cos)) inliers.push_back(i);
    if (inliers.size() < min_count) break;  // the largest plane left is too small: done
    for (const auto i : inliers) tried[i] = 1;  // small patches of it stay in the scene, and are not tried again
    std::size_t behind = 0;
    for (const Vec3& p : points) behind += best.normal.dot(p) - best.d < -3.0f * params.tolerance;
    if (static_cast<float>(behind) > params.max_behind * static_cast<float>(points.size())) continue;  // not background
    Background* b = &background.emplace_back(Background{best, inliers, false});
    flood.run([&, b] {
      for (const auto& patch : patches(points, b->inliers, params.link))
        if (patch.size() >= min_count) {
          for (const auto i : patch) plane[i] = 1;
          b->taken = true;
        }
    });
  }
  flood.wait();
  if (removed)
    for (const Background& b : background)
      if (b.taken) removed->push_back(b.plane);
  return plane;
}

}  // namespace binpose
