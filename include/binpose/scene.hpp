#pragma once
// Scene preparation (thesis 5.2.1-5.2.2): sub-sampling and normals.
#include <binpose/pixel_neighbours.hpp>
#include <binpose/point_grid.hpp>
#include <binpose/types.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace binpose {

/// How the scan is thinned to rho_sub (5.2.1).
enum class Subsampling {
  Random,  ///< the thesis's uniform random selection
  Voxel,   ///< one scan point per cube of side 1/sqrt(rho_sub): even spacing (binpose's)
};

/// The oriented scene points S the matching works on.
struct PreparedScene {
  Points points;                   ///< sub-sampled scan points, mm
  Points normals;                  ///< unit normals facing the sensor
  std::vector<std::uint32_t> scan_index;  ///< each point's index in the full scan
};

/// Indices of one scan point per occupied cube of side `voxel` (the point nearest its cube's
/// centroid), ascending. Deterministic.
std::vector<std::uint32_t> voxelSubsample(const Points& points, float voxel);

/// Indices of the scan points kept at rho_sub (5.2.1), ascending: one per voxel of side
/// 1/sqrt(rho_sub) (points/mm^2), or the thesis's random selection of as many points (seeded).
std::vector<std::uint32_t> subsampleScene(const Points& scan, float rho_sub, Subsampling how, std::uint64_t seed);

/// The chosen scan points (subsampleScene) with normals by plane fits over k neighbours in the
/// full scan (5.2.2) through `scan_grid`, facing `viewpoint` (mm); points whose
/// neighbourhood is degenerate are dropped. `pixels` (of the scan, or null) finds most of the
/// neighbours among pixel neighbours instead, the same ones.
PreparedScene prepareScene(const Points& scan, const PointGrid& scan_grid, std::span<const std::uint32_t> chosen,
                           int k, const Vec3& viewpoint, const PixelNeighbours* pixels = nullptr);

/// The chosen scan points with their `normals` (one per chosen point), without those of a zero
/// normal (a degenerate neighbourhood).
PreparedScene orientedScene(const Points& scan, std::span<const std::uint32_t> chosen, const Points& normals);

/// Redundant sub-groups (5.2.3-5.2.4): a grid of spacing eta over the x-y bounds of the points,
/// and at each node the points within r of it in x-y. Groups smaller than `min_size` are left
/// out; the rest come in the thesis's order, closest to the mean size first (ties by position).
std::vector<std::vector<std::uint32_t>> makeSubGroups(const Points& points, float eta, float r, std::size_t min_size);

}  // namespace binpose
