// Plane-fit normals (thesis 5.2.2).
#include <binpose/normals.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <fmt/format.h>
#include <numeric>
#include <tbb/parallel_for.h>

namespace binpose {

namespace {

/// The plane-fit normal of the `count` points at(0), ..., at(count - 1) (eq. 33-38).
template <class At>
bool planeNormal(std::size_t count, At at, Vec3& normal) {
  if (count < 3) return false;
  double cx = 0, cy = 0, cz = 0;
  for (std::size_t j = 0; j < count; ++j) {
    const Vec3& p = at(j);
    if (!p.allFinite()) return false;
    cx += double(p.x());
    cy += double(p.y());
    cz += double(p.z());
  }
  const auto n = static_cast<double>(count);
  cx /= n;
  cy /= n;
  cz /= n;
  // W = Q^T Q (eq. 33-35), its lower half (all the solver reads) as six sums in registers: an
  // Eigen matrix here went through the stack, and each step's loads waited on its stores.
  double xx = 0, yx = 0, zx = 0, yy = 0, zy = 0, zz = 0;
  for (std::size_t j = 0; j < count; ++j) {
    const Vec3& p = at(j);
    const double x = double(p.x()) - cx, y = double(p.y()) - cy, z = double(p.z()) - cz;
    xx += x * x;
    yx += y * x;
    zx += z * x;
    yy += y * y;
    zy += z * y;
    zz += z * z;
  }
  Eigen::Matrix3d W;
  W << xx, yx, zx, yx, yy, zy, zx, zy, zz;
  // Eigenvalues ascending (eq. 36-38). The closed-form solver (computeDirect) takes a third of
  // the time and gives the same normals to within 3e-6 degrees, but twice (five rounds apart)
  // that was enough to add a wrong pose (score 0.21) to the default preset's PCL milk result.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(W);
  const Eigen::Vector3d lambda = solver.eigenvalues();
  if (solver.info() != Eigen::Success || !(lambda[1] > 1e-12 * std::max(lambda[2], 1e-30))) return false;
  normal = solver.eigenvectors().col(0).cast<float>();
  return normalizeSafe(normal);
}

}  // namespace

bool fitPlaneNormal(const Points& points, Vec3& normal) {
  return planeNormal(points.size(), [&](std::size_t j) -> const Vec3& { return points[j]; }, normal);
}

Points estimateNormals(const Points& cloud, const Points& queries, int k, const Vec3& viewpoint) {
  if (cloud.size() < 3) return Points(queries.size(), Vec3::Zero());
  return estimateNormals(PointGrid(cloud), cloud, queries, k, viewpoint);
}

namespace {

/// The plane-fit normal of query q from its `found` nearest (indices into cloud, any order),
/// oriented towards the viewpoint; zero when the neighbourhood is degenerate.
Vec3 normalFrom(const Points& cloud, const Vec3& q, std::uint32_t* idx, std::size_t found, const Vec3& viewpoint) {
  std::sort(idx, idx + found);  // the fit's sums in one order, whatever the search's
  Vec3 n;
  if (!planeNormal(found, [&](std::size_t j) -> const Vec3& { return cloud[idx[j]]; }, n)) return Vec3::Zero();
  if (n.dot(viewpoint - q) < 0) n = -n;  // towards the sensor
  return n;
}

/// The normals of `count` queries (query(i): the point; not finite, no normal), each from the
/// neighbours nearest(i, q, idx, dist) writes to idx (returning how many, up to k; kLater: not
/// now), given to store(i, normal): what the normal estimates share, the checks, the threads
/// and each thread's buffers.
constexpr std::size_t kLater = ~std::size_t{0};

template <class Query, class Nearest, class Store>
void planeFitNormals(std::size_t count, const Points& cloud, int k, const Vec3& viewpoint, Query query, Nearest nearest,
                     Store store) {
  if (k < 3) throw Error(fmt::format("normal estimation needs k >= 3 neighbours, got {}", k));
  if (cloud.size() < 3) return;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 256), [&](const auto& range) {
    std::vector<std::uint32_t> idx(static_cast<std::size_t>(k));
    std::vector<float> dist(static_cast<std::size_t>(k));
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const Vec3& q = query(i);
      if (!q.allFinite()) continue;
      const std::size_t found = nearest(i, q, idx.data(), dist.data());
      if (found != kLater) store(i, normalFrom(cloud, q, idx.data(), found, viewpoint));
    }
  });
}

}  // namespace

Points estimateNormals(const PointGrid& grid, const Points& cloud, const Points& queries, int k, const Vec3& viewpoint) {
  Points normals(queries.size(), Vec3::Zero());
  planeFitNormals(
      queries.size(), cloud, k, viewpoint, [&](std::size_t i) -> const Vec3& { return queries[i]; },
      [&](std::size_t, const Vec3& q, std::uint32_t* idx, float* dist) { return grid.knn(q, static_cast<std::size_t>(k), idx, dist); },
      [&](std::size_t i, const Vec3& n) { normals[i] = n; });
  return normals;
}

Points pixelNormals(const PixelNeighbours& pixels, const Points& cloud, std::span<const std::uint32_t> chosen, int k,
                    const Vec3& viewpoint, std::vector<std::uint32_t>& deferred) {
  Points normals(chosen.size(), Vec3::Zero());
  std::vector<char> later(chosen.size(), 0);
  planeFitNormals(
      chosen.size(), cloud, k, viewpoint, [&](std::size_t i) -> const Vec3& { return cloud[chosen[i]]; },
      [&](std::size_t i, const Vec3&, std::uint32_t* idx, float* dist) {
        const auto wanted = static_cast<std::size_t>(k);
        if (pixels.knn(chosen[i], wanted, idx, dist)) return wanted;
        later[i] = 1;
        return kLater;
      },
      [&](std::size_t i, const Vec3& n) { normals[i] = n; });
  deferred.clear();
  for (std::size_t i = 0; i < chosen.size(); ++i)
    if (later[i]) deferred.push_back(static_cast<std::uint32_t>(i));
  return normals;
}

void finishNormals(const PointGrid& grid, const Points& cloud, std::span<const std::uint32_t> chosen,
                   std::span<const std::uint32_t> deferred, int k, const Vec3& viewpoint, Points& normals) {
  planeFitNormals(
      deferred.size(), cloud, k, viewpoint, [&](std::size_t d) -> const Vec3& { return cloud[chosen[deferred[d]]]; },
      [&](std::size_t, const Vec3& q, std::uint32_t* idx, float* dist) { return grid.knn(q, static_cast<std::size_t>(k), idx, dist); },
      [&](std::size_t d, const Vec3& n) { normals[deferred[d]] = n; });
}

Points estimateNormals(const PointGrid& grid, const PixelNeighbours* pixels, const Points& cloud,
                       std::span<const std::uint32_t> chosen, int k, const Vec3& viewpoint) {
  // Without pixels every point is left to the grid.
  std::vector<std::uint32_t> deferred;
  Points normals;
  if (pixels != nullptr) {
    normals = pixelNormals(*pixels, cloud, chosen, k, viewpoint, deferred);
  } else {
    normals.assign(chosen.size(), Vec3::Zero());
    deferred.resize(chosen.size());
    std::iota(deferred.begin(), deferred.end(), 0u);
  }
  finishNormals(grid, cloud, chosen, deferred, k, viewpoint, normals);
  return normals;
}

}  // namespace binpose
