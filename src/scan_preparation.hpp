#pragma once
// The first stage of detection (thesis 5.2.1-5.2.2, then the bin's planes): the scan made ready
// for the votes (sub-sampled oriented points, the floor and walls left out) and for
// verification (the full scan's grid, pixel index and range image).
#include "stage_settings.hpp"
#include <binpose/pixel_neighbours.hpp>
#include <binpose/point_grid.hpp>
#include <binpose/refine.hpp>
#include <binpose/scene.hpp>

#include "noise.hpp"

#include <cstddef>
#include <optional>

namespace binpose {

struct PreparedScan {
  PreparedScan() = default;
  PreparedScan(const PreparedScan&) = delete;  // evidence refers to grid and pixels
  PreparedScan& operator=(const PreparedScan&) = delete;

  std::optional<PointGrid> grid;          ///< the full scan's, for the normals, ICP and the score
  std::optional<PixelNeighbours> pixels;  ///< the full scan's pixel index (empty for an unorganized scan)
  PreparedScene scene;                    ///< the oriented points S that vote, without the bin's planes
  std::optional<SceneEvidence> evidence;  ///< the score's view of the scan, the planes as background
  std::size_t sampled_points = 0;         ///< oriented points after sub-sampling
  std::size_t plane_points = 0;           ///< ... of them on the bin's planes, left out of `scene`
  NoiseEstimate noise;                    ///< the scan's, from plane fits on a sample of it
  StageSettings params;                 ///< the parameters adapted to the noise (adapt_to_noise), for every stage
};

/// Sub-samples the scan to rho_sub, fits normals over k_normals neighbours facing the viewpoint,
/// and (remove_planes) takes the bin's floor and walls out of the voting points. Fills `out`,
/// which must outlive nothing but `scan`.
void prepareScan(const PointCloud& scan, const StageSettings& p, PreparedScan& out);

}  // namespace binpose
