#pragma once
// Built-in analytic parts, as closed triangle meshes with outward winding (mm).
#include <binpose/types.hpp>

namespace binpose {

/// Axis-aligned box centred at the origin with the given edge lengths; each face is split into
/// `divisions` x `divisions` squares.
Mesh makeBox(const Vec3& size, int divisions = 1);

/// Icosphere of the given radius centred at the origin; `subdivisions` levels (4 gives 5120 faces).
Mesh makeSphere(float radius, int subdivisions = 4);

}  // namespace binpose
