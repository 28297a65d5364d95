#pragma once
// Even sampling of surfaces and clouds: Poisson-disk dart throwing over a dense candidate pool
// (Cline et al. 2009, the MeshLab filter the thesis used in 6.2).
#include <binpose/types.hpp>

#include <cstdint>

namespace binpose {

/// A point on a mesh surface: its face and barycentric weights (point = w0 a + w1 b + w2 c).
struct SurfacePoint {
  Vec3 point;
  int face = 0;
  Eigen::Vector3f weights;
};

/// Total surface area of a mesh, mm^2.
double meshArea(const Mesh& mesh);

/// `count` points uniformly distributed over the surface (area-weighted), seeded.
std::vector<SurfacePoint> sampleSurfaceUniform(const Mesh& mesh, std::size_t count, std::uint64_t seed);

/// Dart throwing: visits the candidates in a seeded random order and keeps each one farther
/// than `radius` from every kept one. Returns the kept indices: no two closer than `radius`,
/// and every candidate lies within `radius` of a kept one (maximal over the pool).
std::vector<std::uint32_t> poissonDiskSelect(const Points& candidates, float radius, std::uint64_t seed);

/// Poisson-disk selection of about `target` candidates: bisects the radius until the kept count
/// is as close to `target` as it gets. The radius used is written to `radius_out` when given.
std::vector<std::uint32_t> poissonDiskSelectCount(const Points& candidates, std::size_t target, std::uint64_t seed,
                                                  float* radius_out = nullptr);

}  // namespace binpose
