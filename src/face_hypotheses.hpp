#pragma once
// Beyond the thesis: poses of a copy that shows the sensor one flat face only (a gear or a plate
// lying flat, a box seen from above). Its point-pair features are those of any flat patch
// (alpha and the normals' angles all 90 degrees), so its votes cannot tell where on the part a
// point lies, and no clique forms. A flat region of the scan that no detection explains, as large
// as one of the model's flat faces, fixes the face's plane and centre; the turn about its normal
// is the one the scan supports best (the face's outline), and verification judges the pose as any other.
#include "group_schedule.hpp"
#include "model_shape.hpp"
#include "subgroup_matcher.hpp"

#include <vector>

namespace binpose {

/// A flat face of the model, in the model's frame.
struct ModelFace {
  Vec3 normal;    ///< outward unit normal
  Vec3 centre;    ///< its points' centroid, mm
  float area = 0; ///< mm^2
  bool turns = true;  ///< false when the part's axis of revolution lies along the normal: every turn about it is the same pose
  float spread[2] = {0, 0};  ///< RMS distance of its points from the centre along its principal axes, largest first, mm
  Vec3 axes[2] = {Vec3::UnitX(), Vec3::UnitY()};  ///< those principal axes (unit, in its plane), largest first
};

/// The model's flat faces of at least `min_area` mm^2: its points grown into regions of one plane
/// (neighbours within two sample spacings, normals within a few degrees). `area_per_point`: the
/// model's surface area over its point count, mm^2.
/// `revolution_axis`: the direction of the part's axis of revolution, when it has one (else null).
std::vector<ModelFace> flatFaces(const Points& points, const Points& normals, float sample_radius,
                                 float area_per_point, float min_area, const Vec3* revolution_axis = nullptr);

/// The detections of copies seen by one flat face, from the scene's flat regions that no
/// detection in `state` explains (not removed; a region that is not one plane split into the
/// planes it holds), verified as the sub-groups' (min_score, visible support, outline), standing
/// out of the scan around them, and added to `state` with their points removed. Deterministic.
void addFaceDetections(const std::vector<ModelFace>& faces, const Matcher& matcher, const ModelShape& shape,
                       MatchState& state);

}  // namespace binpose
