#pragma once
// Surface normals by least-squares plane fits (thesis 5.2.2, eq. 30-38).
#include <binpose/pixel_neighbours.hpp>
#include <binpose/point_grid.hpp>
#include <binpose/types.hpp>

#include <atomic>
#include <span>
#include <vector>

namespace binpose {

/// Normal of the plane fitted to `points` (eq. 30-38): the eigenvector of the smallest eigenvalue
/// of the scatter matrix W = Q^T Q about the centroid. False for fewer than 3 points, a
/// non-finite point, or a degenerate (collinear) neighbourhood.
bool fitPlaneNormal(const Points& points, Vec3& normal);
/// The same for the points of `points` at the indices `which`.
bool fitPlaneNormal(const Points& points, std::span<const std::uint32_t> which, Vec3& normal);

/// Normals of `queries` from their `k` nearest neighbours in `cloud` (the query itself included
/// when it is a cloud point; thesis: k = 6 on the full scan), each oriented towards `viewpoint`.
/// A query whose neighbourhood is degenerate gets a zero normal (missing), never NaN. Parallel.
Points estimateNormals(const Points& cloud, const Points& queries, int k, const Vec3& viewpoint);
/// The same with a grid of `cloud` already built.
Points estimateNormals(const PointGrid& grid, const Points& cloud, const Points& queries, int k, const Vec3& viewpoint);
/// The same for queries that are the cloud's own points (indices `chosen`). Where `pixels`
/// (of the same cloud; may be null) proves a point's k nearest from its pixel's neighbours, the
/// grid is not searched: the same neighbours, so the same normals (BM_NormalsAtScanPoints:
/// 8.5 -> 6.8 ms on the cap bin).
Points estimateNormals(const PointGrid& grid, const PixelNeighbours* pixels, const Points& cloud,
                       std::span<const std::uint32_t> chosen, int k, const Vec3& viewpoint);

/// A plane fit whose eigenvector is left for later: its scatter matrix W (eq. 33-35) and W's
/// eigenvalues in closed form, ascending.
struct PendingFit {
  Eigen::Matrix3d W;
  Eigen::Vector3d lambda;
};

/// Normals of the chosen cloud points (indices `chosen`) from every cloud point within `radius`
/// of each (a metric neighbourhood, for a scan too noisy for any k the pixel search answers:
/// StageSettings::normal_radius), each oriented towards `viewpoint`; a zero normal where fewer
/// than three points or a degenerate set lie within it. Parallel; the same normals whatever the
/// thread count.
Points radiusNormals(const PointGrid& grid, const Points& cloud, std::span<const std::uint32_t> chosen, float radius,
                     const Vec3& viewpoint);

/// That estimate in two halves, the first while the grid is being built: the normals of the
/// chosen points whose k nearest `pixels` proves, and of the others through the grid once
/// `grid` (when given) holds it; the places in `chosen` of those left over are listed in
/// `deferred` (in order; zero normals until finishNormals gives them theirs through the grid).
/// With `pending` (one per chosen point), a normal that would need Eigen's iterative solver
/// (a third of a bin's, most of them on its floor and walls, which plane removal drops) is
/// left NaN, its fit kept in its place in `pending` (finishPending gives the same normal),
/// where its neighbourhood is sure not to be degenerate.
Points pixelNormals(const PixelNeighbours& pixels, const Points& cloud, std::span<const std::uint32_t> chosen, int k,
                    const Vec3& viewpoint, std::vector<std::uint32_t>& deferred,
                    const std::atomic<const PointGrid*>* grid = nullptr, std::vector<PendingFit>* pending = nullptr);
void finishNormals(const PointGrid& grid, const Points& cloud, std::span<const std::uint32_t> chosen,
                   std::span<const std::uint32_t> deferred, int k, const Vec3& viewpoint, Points& normals,
                   std::vector<PendingFit>* pending = nullptr);

/// A pending fit's normal at point q, as the estimate would have given it; false when the
/// solver finds it degenerate after all (which its eigenvalues rule out).
bool finishPending(const PendingFit& fit, const Vec3& q, const Vec3& viewpoint, Vec3& normal);

/// Whether a pending fit's normal n would pass |m . n| >= min_cos (m a unit vector), settled
/// from its eigenvalues without the solver: 1 yes, 0 no, -1 too close to call (then finish it).
int pendingAligned(const PendingFit& fit, const Vec3& m, float min_cos);

namespace detail {
/// Eq. 36-38 on a scatter matrix W (symmetric): the unit eigenvector of its least eigenvalue in
/// float; false when W is degenerate (its two least eigenvalues both about zero). With
/// `closed_form`, found in closed form where that is proved to give the very floats of Eigen's
/// iterative solver (up to the sign), by the solver elsewhere; without, by the solver alone.
/// `answered_closed`, when given, tells which answered.
bool scatterNormal(const Eigen::Matrix3d& W, Vec3& normal, bool closed_form = true, bool* answered_closed = nullptr);
}  // namespace detail

}  // namespace binpose
