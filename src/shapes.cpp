#include <binpose/shapes.hpp>

#include <fmt/format.h>

#include <map>

namespace binpose {

Mesh makeBox(const Vec3& size, int divisions) {
  if (divisions < 1) throw Error(fmt::format("box divisions must be >= 1, got {}", divisions));
  Mesh mesh;
  const Vec3 half = 0.5f * size;
  for (int axis = 0; axis < 3; ++axis)
    for (const float side : {-1.0f, 1.0f}) {
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;  // (u, v, axis) is right-handed
      const int base = static_cast<int>(mesh.vertices.size());
      for (int i = 0; i <= divisions; ++i)
        for (int j = 0; j <= divisions; ++j) {
          Vec3 p;
          p[axis] = side * half[axis];
          p[u] = -half[u] + size[u] * float(i) / float(divisions);
          p[v] = -half[v] + size[v] * float(j) / float(divisions);
          mesh.vertices.push_back(p);
        }
      auto id = [&](int i, int j) { return base + i * (divisions + 1) + j; };
      for (int i = 0; i < divisions; ++i)
        for (int j = 0; j < divisions; ++j) {
          Eigen::Vector3i a(id(i, j), id(i + 1, j), id(i + 1, j + 1)), b(id(i, j), id(i + 1, j + 1), id(i, j + 1));
          if (side < 0) { std::swap(a[1], a[2]); std::swap(b[1], b[2]); }  // u x v = +axis: flip on the - side
          mesh.faces.push_back(a);
          mesh.faces.push_back(b);
        }
    }
  return mesh;
}

Mesh makeSphere(float radius, int subdivisions) {
  if (!(radius > 0) || subdivisions < 0 || subdivisions > 7)
    throw Error(fmt::format("sphere needs radius > 0 and 0..7 subdivisions, got {} and {}", radius, subdivisions));
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  Mesh m;
  m.vertices = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  m.faces = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
             {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
             {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (Vec3& v : m.vertices) v.normalize();
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<int, int>, int> midpoint;
    auto mid = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      if (auto it = midpoint.find(key); it != midpoint.end()) return it->second;
      m.vertices.push_back((m.vertices[a] + m.vertices[b]).normalized());
      return midpoint[key] = static_cast<int>(m.vertices.size()) - 1;
    };
    std::vector<Eigen::Vector3i> faces;
    for (const auto& f : m.faces) {
      const int a = mid(f[0], f[1]), b = mid(f[1], f[2]), c = mid(f[2], f[0]);
      faces.insert(faces.end(), {{f[0], a, c}, {f[1], b, a}, {f[2], c, b}, {a, b, c}});
    }
    m.faces = std::move(faces);
  }
  for (Vec3& v : m.vertices) v *= radius;
  return m;
}

}  // namespace binpose
