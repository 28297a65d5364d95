// Plane-fit normals (thesis 5.2.2).
#include <binpose/normals.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <fmt/format.h>
#include <tbb/parallel_for.h>

namespace binpose {

bool fitPlaneNormal(const Points& points, Vec3& normal) {
  if (points.size() < 3) return false;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Vec3& p : points) {
    if (!p.allFinite()) return false;
    centroid += p.cast<double>();
  }
  centroid /= static_cast<double>(points.size());
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();  // W = Q^T Q (eq. 33-35)
  for (const Vec3& p : points) {
    const Eigen::Vector3d q = p.cast<double>() - centroid;
    W += q * q.transpose();
  }
  // Eigenvalues ascending (eq. 36-38). The closed-form solver (computeDirect) takes a third of
  // the time and gives the same normals to within 3e-6 degrees, but twice (five rounds apart)
  // that was enough to add a wrong pose (score 0.21) to the default preset's PCL milk result.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(W);
  const Eigen::Vector3d lambda = solver.eigenvalues();
  if (solver.info() != Eigen::Success || !(lambda[1] > 1e-12 * std::max(lambda[2], 1e-30))) return false;
  normal = solver.eigenvectors().col(0).cast<float>();
  return normalizeSafe(normal);
}

Points estimateNormals(const Points& cloud, const Points& queries, int k, const Vec3& viewpoint) {
  if (cloud.size() < 3) return Points(queries.size(), Vec3::Zero());
  return estimateNormals(PointGrid(cloud), cloud, queries, k, viewpoint);
}

namespace {

/// The plane-fit normal of query q from its `found` nearest (indices into cloud, any order),
/// oriented towards the viewpoint; zero when the neighbourhood is degenerate.
Vec3 normalFrom(const Points& cloud, const Vec3& q, std::uint32_t* idx, std::size_t found, const Vec3& viewpoint,
                Points& neighbours) {
  std::sort(idx, idx + found);  // the fit's sums in one order, whatever the search's
  neighbours.clear();
  for (std::size_t j = 0; j < found; ++j) neighbours.push_back(cloud[idx[j]]);
  Vec3 n;
  if (!fitPlaneNormal(neighbours, n)) return Vec3::Zero();
  if (n.dot(viewpoint - q) < 0) n = -n;  // towards the sensor
  return n;
}

/// The normals of `count` queries (query(i): the point; not finite, no normal), each from the
/// neighbours nearest(i, q, idx, dist) writes to idx (returning how many, up to k): what both
/// estimateNormals below share, the checks, the threads and each thread's buffers.
template <class Query, class Nearest>
Points planeFitNormals(std::size_t count, const Points& cloud, int k, const Vec3& viewpoint, Query query, Nearest nearest) {
  if (k < 3) throw Error(fmt::format("normal estimation needs k >= 3 neighbours, got {}", k));
  Points normals(count, Vec3::Zero());
  if (cloud.size() < 3) return normals;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 256), [&](const auto& range) {
    std::vector<std::uint32_t> idx(static_cast<std::size_t>(k));
    std::vector<float> dist(static_cast<std::size_t>(k));
    Points neighbours;
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const Vec3& q = query(i);
      if (!q.allFinite()) continue;
      const std::size_t found = nearest(i, q, idx.data(), dist.data());
      normals[i] = normalFrom(cloud, q, idx.data(), found, viewpoint, neighbours);
    }
  });
  return normals;
}

}  // namespace

Points estimateNormals(const PointGrid& grid, const Points& cloud, const Points& queries, int k, const Vec3& viewpoint) {
  return planeFitNormals(
      queries.size(), cloud, k, viewpoint, [&](std::size_t i) -> const Vec3& { return queries[i]; },
      [&](std::size_t, const Vec3& q, std::uint32_t* idx, float* dist) { return grid.knn(q, static_cast<std::size_t>(k), idx, dist); });
}

Points estimateNormals(const PointGrid& grid, const PixelNeighbours* pixels, const Points& cloud,
                       std::span<const std::uint32_t> chosen, int k, const Vec3& viewpoint) {
  return planeFitNormals(
      chosen.size(), cloud, k, viewpoint, [&](std::size_t i) -> const Vec3& { return cloud[chosen[i]]; },
      [&](std::size_t i, const Vec3& q, std::uint32_t* idx, float* dist) {
        const auto wanted = static_cast<std::size_t>(k);
        return pixels != nullptr && pixels->knn(chosen[i], wanted, idx, dist) ? wanted : grid.knn(q, wanted, idx, dist);
      });
}

}  // namespace binpose
