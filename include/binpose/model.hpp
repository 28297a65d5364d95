#pragma once
// Offline model preparation (thesis chapter 6): an even sampling of the part's surface with a
// normal at every point.
#include <binpose/types.hpp>

#include <cstdint>

namespace binpose {

/// The thesis's test part measures tau_object = 60 mm; its distance-like parameters are scaled
/// by (model diameter / 60 mm) for other parts (thesisScale).
inline constexpr float kThesisPartSize = 60.0f;
inline float thesisScale(float model_diameter) { return model_diameter / kThesisPartSize; }

struct ModelParams {
  int num_points = 4000;       ///< n_M, model points after sampling (thesis 7.3, "hash model size")
  double rho_model = 0.0;      ///< rho_model, points/mm^2; when > 0 it sets n_M = rho_model * area
  int normal_k = 6;            ///< neighbours for plane-fit normals of point-cloud models (thesis 5.2.2)
  double crease_angle_deg = 30.0;  ///< faces meeting at a sharper angle keep their own normal
  std::uint64_t seed = 1;      ///< sampling seed
};

/// Oriented model points, mm, with unit normals pointing out of the part.
struct OrientedModel {
  Points points;
  Points normals;
  float diameter = 0;      ///< largest distance between two model points, mm
  double area = 0;         ///< surface area, mm^2 (0 when unknown: a point-cloud model)
  float sample_radius = 0; ///< Poisson-disk radius used, mm
};

/// Per-face unit normals, oriented outwards: by the file's vertex normals when it has them;
/// otherwise each connected surface (faces sharing edges, vertices matched by position) wound
/// consistently, as most of its faces are, then all turned by the sign of the enclosed volume.
/// Degenerate faces get a zero normal.
Points faceNormals(const Mesh& mesh);

/// Poisson-disk samples of the surface with crease-aware interpolated face normals.
OrientedModel prepareModel(const Mesh& mesh, const ModelParams& params);

/// An even Poisson-disk sub-sampling of a point-cloud model; its own normals where it has them,
/// plane-fit normals (oriented to the cloud's viewpoint) where it does not. Points without a
/// usable normal are dropped.
OrientedModel prepareModel(const PointCloud& cloud, const ModelParams& params);

/// Area of the points' bounding rectangle across their two longest principal axes, mm^2: a
/// bound on the largest flat face the part can show (exact for a box).
float boundingFaceArea(const Points& points);

}  // namespace binpose
