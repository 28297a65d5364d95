#pragma once
// Built-in analytic parts, as closed triangle meshes with outward winding (mm).
#include <binpose/io.hpp>
#include <binpose/types.hpp>

#include <string>

namespace binpose {

/// Axis-aligned box centred at the origin with the given edge lengths; each face is split into
/// `divisions` x `divisions` squares.
Mesh makeBox(const Vec3& size, int divisions = 1);

/// Icosphere of the given radius centred at the origin; `subdivisions` levels (4 gives 5120 faces).
Mesh makeSphere(float radius, int subdivisions = 4);

/// Dimensions of the built-in detergent-bottle cap (thesis 7.1: about 60 mm across,
/// rotationally symmetric, with flat, cylindrical and sharply curved regions). mm.
struct CapParams {
  float radius = 30.0f;        ///< outer radius
  float height = 20.0f;        ///< outer height
  float wall = 2.0f;           ///< wall and top thickness
  float fillet = 4.0f;         ///< radius of the rounded edge between top and side
  int segments = 96;           ///< facets around the axis
  int fillet_segments = 10;    ///< facets along the fillet
};

/// A closed cap mesh: the axis is +z, the open mouth at z = 0, the top at z = height.
Mesh makeCap(const CapParams& params = {});

/// A built-in part by name ("cap", "sphere", "box"); throws for an unknown name.
Mesh builtinPart(const std::string& name);

/// A model file (readModelFile, lengths times `scale`), or the built-in part "builtin:NAME" (mm).
ModelFile readModelOrBuiltin(const std::string& spec, double scale = 1.0);

}  // namespace binpose
