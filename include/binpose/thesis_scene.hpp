#pragma once
// Synthetic scenes as the thesis made them (7.4): copies of the part at random poses, apart,
// with no bin, floor or sensor; each copy's points drawn at random from the mesh (not the
// database's samples) on the side that faces the viewer, then cut by a random occluder so that
// the visible surface varies from copy to copy (recognition rate against visible surface,
// Figures 37-38). Exact poses and visible fractions go with them.
#include <binpose/simulation.hpp>

namespace binpose {

struct ThesisSceneParams {
  int instances = 16;
  std::uint64_t seed = 1;
  float density = 0.5f;      ///< points drawn per mm^2 of the part's whole surface
  float distance = 500.0f;   ///< the copies' plane from the viewpoint (the origin), mm
  float spacing = 1.25f;     ///< grid step between copies, in part diameters (they never touch)
  float min_kept = 0.25f;    ///< the occluder keeps a share of each copy's visible side uniform in
  float max_kept = 1.0f;     ///< [min_kept, max_kept]
  float noise_sigma = 0.0f;  ///< Gaussian noise along the line of sight, mm (the thesis: none)
};

/// The scene in the viewer's frame (origin, looking along +z): an unorganized cloud without
/// normals; each instance's pose (model -> scene), visible_fraction (points kept over points
/// drawn on its whole surface) and visib_fract (kept over its unoccluded visible side).
SimulatedScene simulateThesisScene(const Mesh& mesh, const ThesisSceneParams& params);

}  // namespace binpose
