#pragma once
// Internal: oriented points as coordinate arrays, for loops that take four or eight points at a
// time (SIMD lanes): the plane search's hypothesis scores, ICP's posing of model points.
#include <binpose/types.hpp>

#include <array>
#include <cstddef>
#include <vector>

namespace binpose::detail {

/// `size` oriented points as six arrays (x, y, z, nx, ny, nz), each padded with zeros to a
/// multiple of 4, so that a load of four lanes from any point stays inside.
struct OrientedLanes {
  std::array<std::vector<float>, 6> c;
  std::size_t size = 0;

  /// The points and normals at(0), ..., at(count - 1) (indices into both).
  template <class At>
  void assign(const Points& points, const Points& normals, std::size_t count, At at) {
    size = count;
    for (auto& v : c) v.assign((count + 3) / 4 * 4, 0.0f);
    for (std::size_t k = 0; k < count; ++k) {
      const std::size_t i = at(k);
      for (int a = 0; a < 3; ++a) {
        c[a][k] = points[i][a];
        c[3 + a][k] = normals[i][a];
      }
    }
  }
};

}  // namespace binpose::detail
