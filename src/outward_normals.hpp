#pragma once
// A point-cloud model's normals turned outwards: a model given as points alone, all round the
// part (samples of a CAD model, a reference scan merged from several views), has no viewpoint
// that every normal faces.
#include <binpose/types.hpp>

namespace binpose {

/// Turns `normals` (unit, of `points`; zero where there is none, left so) to point out of the
/// part, consistently from point to point (Hoppe et al. 1992: along a minimum spanning tree of the
/// neighbour graph weighted by 1 - |n_i . n_j|, so that the sign passes between near-parallel
/// normals first). A neighbour counts only near both points' tangent planes: the other side of a
/// thin plate lies across them. Each connected piece is then turned as most rays along and
/// against its normals say (out of a closed surface a ray crosses it an even number of times, into
/// it an odd one). Deterministic.
void orientOutward(const Points& points, Points& normals);

}  // namespace binpose
