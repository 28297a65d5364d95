// Plane-fit normals (thesis 5.2.2).
#include <binpose/normals.hpp>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <fmt/format.h>
#include <limits>
#include <numeric>
#include <tbb/parallel_for.h>

namespace binpose {

namespace {

/// Eq. 36-38 by Eigen's iterative solver: the eigenvector of W's least eigenvalue, as a float
/// unit vector; false when W is degenerate (its two least eigenvalues both about zero).
bool iterativeNormal(const Eigen::Matrix3d& W, Vec3& normal) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(W);
  const Eigen::Vector3d lambda = solver.eigenvalues();
  if (solver.info() != Eigen::Success || !(lambda[1] > 1e-12 * std::max(lambda[2], 1e-30))) return false;
  normal = solver.eigenvectors().col(0).cast<float>();
  return normalizeSafe(normal);
}

/// The same eigenvector in closed form, when that is sure to give the iterative solver's float
/// normal; false when it is not (then ask the solver). The eigenvalues are Eigen's closed form
/// (computeDirect: the roots of W's characteristic cubic), the eigenvector the largest cross
/// product of two rows of W - lambda_0 I. The solver's eigenvector lies within a few
/// eps ||W|| / gap of the exact one (gap = lambda_1 - lambda_0; it is backward stable); the
/// cubic's root within a few eps ||W||^2 / gap, and so the cross product within a few
/// eps (||W|| / gap)^2. When every coordinate stays in one float's rounding interval across a
/// margin far wider than both, 1e-12 (||W|| / gap)^2 (over 4000 times), both round to the same
/// floats, up to the sign, which normalizeSafe keeps and the caller's turn towards the
/// viewpoint settles. A gap under 1e-3 ||W|| is left to the solver, as is a coordinate within
/// the margin of a rounding boundary: on the bench's bins about a third of the normals, most
/// of them on the bin's floor and walls, whose coordinates along the scan's axes are zero or
/// nearly so. (computeDirect's own eigenvectors, used alone, changed normals in their last
/// bits, and the votes followed.)
bool closedFormNormal(const Eigen::Matrix3d& W, Eigen::Vector3d& v, Eigen::Vector3d& lambda) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> roots;
  roots.computeDirect(W, Eigen::EigenvaluesOnly);
  lambda = roots.eigenvalues();  // ascending
  const double norm = std::max(std::abs(lambda[0]), std::abs(lambda[2]));  // ||W||
  const double gap = lambda[1] - lambda[0];
  if (!(norm > 0) || !std::isfinite(norm) || !(gap >= 1e-3 * norm)) return false;
  Eigen::Matrix3d B = W;
  B.diagonal().array() -= lambda[0];
  const Eigen::Vector3d r0 = B.row(0), r1 = B.row(1), r2 = B.row(2);
  const Eigen::Vector3d cross[3] = {r0.cross(r1), r0.cross(r2), r1.cross(r2)};
  const double n[3] = {cross[0].squaredNorm(), cross[1].squaredNorm(), cross[2].squaredNorm()};
  const int best = n[0] >= n[1] ? (n[0] >= n[2] ? 0 : 2) : (n[1] >= n[2] ? 1 : 2);
  if (!(n[best] > 0) || !std::isfinite(n[best])) return false;
  v = cross[best] / std::sqrt(n[best]);
  const double ratio = norm / gap, margin = 1e-12 * ratio * ratio;
  for (int i = 0; i < 3; ++i)
    if (static_cast<float>(v[i] - margin) != static_cast<float>(v[i] + margin)) return false;  // zeros too
  return true;
}

}  // namespace

namespace detail {

bool scatterNormal(const Eigen::Matrix3d& W, Vec3& normal, bool closed_form, bool* answered_closed) {
  Eigen::Vector3d v, lambda;
  const bool closed = closed_form && closedFormNormal(W, v, lambda);
  if (answered_closed != nullptr) *answered_closed = closed;
  if (closed) {
    normal = v.cast<float>();
    return normalizeSafe(normal);
  }
  return iterativeNormal(W, normal);
}

}  // namespace detail

namespace {

/// A plane fit's outcome: its normal, a degenerate neighbourhood, or its normal left pending.
enum class Fit { kNormal, kDegenerate, kPending };

/// scatterNormal, or with `pending` (not null) kPending where it would need the iterative solver
/// and W is sure not to be degenerate: W and its eigenvalues kept in *pending. The closed
/// form's eigenvalues lie within about sqrt(eps) ||W|| (1.5e-8) of the exact ones even where
/// two cluster, so a second least over a millionth of the largest keeps the solver's (within a
/// few eps ||W||) over its 1e-12 bound. (Should the solver still fail, finishPending says so.)
Fit scatterFit(const Eigen::Matrix3d& W, Vec3& normal, PendingFit* pending) {
  Eigen::Vector3d v, lambda;
  if (closedFormNormal(W, v, lambda)) {
    normal = v.cast<float>();
    return normalizeSafe(normal) ? Fit::kNormal : Fit::kDegenerate;
  }
  if (pending != nullptr && lambda.allFinite() && lambda[2] > 0 && lambda[1] >= 1e-6 * lambda[2]) {
    pending->W = W;
    pending->lambda = lambda;
    return Fit::kPending;
  }
  return iterativeNormal(W, normal) ? Fit::kNormal : Fit::kDegenerate;
}

/// The scatter matrix W = Q^T Q (eq. 33-35) of the `count` points at(0), ..., at(count - 1)
/// about their centroid; false for fewer than 3 points or a non-finite one.
template <class At>
bool scatterOf(std::size_t count, At at, Eigen::Matrix3d& W) {
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
  W << xx, yx, zx, yx, yy, zy, zx, zy, zz;
  return true;
}

/// The plane-fit normal of the `count` points at(0), ..., at(count - 1) (eq. 33-38).
template <class At>
bool planeNormal(std::size_t count, At at, Vec3& normal) {
  Eigen::Matrix3d W;
  return scatterOf(count, at, W) && detail::scatterNormal(W, normal);
}

}  // namespace

bool fitPlaneNormal(const Points& points, Vec3& normal) {
  return planeNormal(points.size(), [&](std::size_t j) -> const Vec3& { return points[j]; }, normal);
}

bool fitPlaneNormal(const Points& points, std::span<const std::uint32_t> which, Vec3& normal) {
  return planeNormal(which.size(), [&](std::size_t j) -> const Vec3& { return points[which[j]]; }, normal);
}

Points estimateNormals(const Points& cloud, const Points& queries, int k, const Vec3& viewpoint) {
  if (cloud.size() < 3) return Points(queries.size(), Vec3::Zero());
  return estimateNormals(PointGrid(cloud), cloud, queries, k, viewpoint);
}

namespace {

/// n turned towards the sensor at `viewpoint` from the point q it was fitted at.
Vec3 facingViewpoint(const Vec3& n, const Vec3& q, const Vec3& viewpoint) { return n.dot(viewpoint - q) < 0 ? Vec3(-n) : n; }

/// The plane-fit normal of query q from its `found` nearest (indices into cloud, any order),
/// oriented towards the viewpoint; zero when the neighbourhood is degenerate. With `pending`
/// (not null), NaN where the fit is left pending in it (scatterFit).
Vec3 normalFrom(const Points& cloud, const Vec3& q, std::uint32_t* idx, std::size_t found, const Vec3& viewpoint,
                PendingFit* pending = nullptr) {
  std::sort(idx, idx + found);  // the fit's sums in one order, whatever the search's
  Eigen::Matrix3d W;
  Vec3 n;
  if (!scatterOf(found, [&](std::size_t j) -> const Vec3& { return cloud[idx[j]]; }, W)) return Vec3::Zero();
  switch (scatterFit(W, n, pending)) {
    case Fit::kDegenerate: return Vec3::Zero();
    case Fit::kPending: return Vec3::Constant(std::numeric_limits<float>::quiet_NaN());
    case Fit::kNormal: break;
  }
  return facingViewpoint(n, q, viewpoint);
}

/// The normals of `count` queries (query(i): the point; not finite, no normal), each from the
/// neighbours nearest(i, q, idx, dist) writes to idx (returning how many, up to k; kLater: not
/// now), given to store(i, normal): what the normal estimates share, the checks, the threads
/// and each thread's buffers.
constexpr std::size_t kLater = ~std::size_t{0};

/// Where query i's fit may be left pending (pending(i)), or nowhere (null).
PendingFit* pendingSlot(std::nullptr_t, std::size_t) { return nullptr; }
template <class Pending>
PendingFit* pendingSlot(const Pending& pending, std::size_t i) { return pending(i); }

template <class Query, class Nearest, class Store, class Pending = std::nullptr_t>
void planeFitNormals(std::size_t count, const Points& cloud, int k, const Vec3& viewpoint, Query query, Nearest nearest,
                     Store store, Pending pending = nullptr) {
  if (k < 3) throw Error(fmt::format("normal estimation needs k >= 3 neighbours, got {}", k));
  if (cloud.size() < 3) return;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 256), [&](const auto& range) {
    std::vector<std::uint32_t> idx(static_cast<std::size_t>(k));
    std::vector<float> dist(static_cast<std::size_t>(k));
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const Vec3& q = query(i);
      if (!q.allFinite()) continue;
      const std::size_t found = nearest(i, q, idx.data(), dist.data());
      if (found != kLater)
        store(i, normalFrom(cloud, q, idx.data(), found, viewpoint, pendingSlot(pending, i)));
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
                    const Vec3& viewpoint, std::vector<std::uint32_t>& deferred, const std::atomic<const PointGrid*>* grid,
                    std::vector<PendingFit>* pending) {
  if (pending != nullptr) pending->resize(chosen.size());
  Points normals(chosen.size(), Vec3::Zero());
  std::vector<char> later(chosen.size(), 0);
  planeFitNormals(
      chosen.size(), cloud, k, viewpoint, [&](std::size_t i) -> const Vec3& { return cloud[chosen[i]]; },
      [&](std::size_t i, const Vec3& q, std::uint32_t* idx, float* dist) {
        const auto wanted = static_cast<std::size_t>(k);
        if (pixels.knn(chosen[i], wanted, idx, dist)) return wanted;
        if (const PointGrid* g = grid != nullptr ? grid->load(std::memory_order_acquire) : nullptr) return g->knn(q, wanted, idx, dist);
        later[i] = 1;
        return kLater;
      },
      [&](std::size_t i, const Vec3& n) { normals[i] = n; },
      [&](std::size_t i) { return pending != nullptr ? &(*pending)[i] : nullptr; });
  deferred.clear();
  for (std::size_t i = 0; i < chosen.size(); ++i)
    if (later[i]) deferred.push_back(static_cast<std::uint32_t>(i));
  return normals;
}

Points radiusNormals(const PointGrid& grid, const Points& cloud, std::span<const std::uint32_t> chosen, float radius,
                     const Vec3& viewpoint) {
  Points normals(chosen.size(), Vec3::Zero());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chosen.size(), 64), [&](const auto& range) {
    std::vector<std::uint32_t> idx;
    for (std::size_t i = range.begin(); i != range.end(); ++i) {
      const Vec3& q = cloud[chosen[i]];
      if (!q.allFinite()) continue;
      grid.within(q, radius, idx);
      normals[i] = normalFrom(cloud, q, idx.data(), idx.size(), viewpoint);  // sorted there: one sum order
    }
  });
  return normals;
}

void finishNormals(const PointGrid& grid, const Points& cloud, std::span<const std::uint32_t> chosen,
                   std::span<const std::uint32_t> deferred, int k, const Vec3& viewpoint, Points& normals,
                   std::vector<PendingFit>* pending) {
  planeFitNormals(
      deferred.size(), cloud, k, viewpoint, [&](std::size_t d) -> const Vec3& { return cloud[chosen[deferred[d]]]; },
      [&](std::size_t, const Vec3& q, std::uint32_t* idx, float* dist) { return grid.knn(q, static_cast<std::size_t>(k), idx, dist); },
      [&](std::size_t d, const Vec3& n) { normals[deferred[d]] = n; },
      [&](std::size_t d) { return pending != nullptr ? &(*pending)[deferred[d]] : nullptr; });
}

bool finishPending(const PendingFit& fit, const Vec3& q, const Vec3& viewpoint, Vec3& normal) {
  if (!iterativeNormal(fit.W, normal)) return false;
  normal = facingViewpoint(normal, q, viewpoint);
  return true;
}

int pendingAligned(const PendingFit& fit, const Vec3& m, float min_cos) {
  // With W's eigenvalues l0 <= l1 <= l2 and u's squared cosines c_i^2 with their eigenvectors
  // (summing to 1), the Rayleigh quotient r = u^T W u = sum l_i c_i^2 bounds c_0^2 from both
  // sides: (l1 - r) / (l1 - l0) <= c_0^2 <= (l2 - r) / (l2 - l0). The normal is the first
  // eigenvector to within a float's rounding and the solver's eps ||W|| / gap, and the closed
  // form's eigenvalues err by far less than the margin's 1e-3 on the cosine.
  const Eigen::Vector3d& l = fit.lambda;
  if (!(l[1] - l[0] >= 1e-3 * l[2])) return -1;
  const Eigen::Vector3d u = m.cast<double>().normalized();
  const double r = u.dot(fit.W * u);
  const double lower = (l[1] - r) / (l[1] - l[0]), upper = (l[2] - r) / (l[2] - l[0]);
  constexpr double kMargin = 1e-3;
  if (lower >= (double(min_cos) + kMargin) * (double(min_cos) + kMargin)) return 1;
  if (double(min_cos) > kMargin && upper <= (double(min_cos) - kMargin) * (double(min_cos) - kMargin)) return 0;
  return -1;
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
