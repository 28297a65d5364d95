#include <binpose/shapes.hpp>

#include <binpose/geometry.hpp>

#include <fmt/format.h>

#include <cmath>
#include <map>
#include <string_view>

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
  weldVertices(mesh);  // faces share the vertices along the box's edges
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

namespace {

/// Revolves a closed (r, z) profile about the z axis; points with r == 0 become poles.
Mesh revolve(const std::vector<Eigen::Vector2f>& profile, int segments) {
  Mesh m;
  std::vector<std::vector<int>> rings;
  for (const auto& rz : profile) {
    std::vector<int> ring;
    if (rz.x() <= 0.0f) {
      m.vertices.emplace_back(0.0f, 0.0f, rz.y());
      ring.assign(static_cast<std::size_t>(segments), static_cast<int>(m.vertices.size()) - 1);
    } else {
      for (int k = 0; k < segments; ++k) {
        const float a = 2.0f * float(M_PI) * float(k) / float(segments);
        ring.push_back(static_cast<int>(m.vertices.size()));
        m.vertices.emplace_back(rz.x() * std::cos(a), rz.x() * std::sin(a), rz.y());
      }
    }
    rings.push_back(std::move(ring));
  }
  for (std::size_t p = 0; p + 1 < rings.size(); ++p)
    for (int k = 0; k < segments; ++k) {
      const int k1 = (k + 1) % segments;
      const int a0 = rings[p][k], a1 = rings[p][k1], b0 = rings[p + 1][k], b1 = rings[p + 1][k1];
      if (a0 != a1) m.faces.emplace_back(a0, a1, b1);  // skipped where ring a is a pole
      if (b0 != b1) m.faces.emplace_back(a0, b1, b0);  // skipped where ring b is a pole
    }
  return m;
}

}  // namespace

Mesh makeCap(const CapParams& c) {
  if (!(c.radius > 0) || !(c.height > 0) || !(c.wall > 0) || c.wall * 2 >= c.radius || c.wall >= c.height ||
      !(c.fillet >= 0) || c.fillet >= c.height - c.wall || c.fillet >= c.radius - c.wall || c.segments < 8 ||
      c.fillet_segments < 1)
    throw Error("cap parameters are inconsistent (need radius > 2 wall, height > wall + fillet, segments >= 8)");
  // Profile from the outer top pole, over the fillet, down the outside, across the rim, up the
  // inside to the inner top pole. The material lies to the right of the walk.
  std::vector<Eigen::Vector2f> profile{{0.0f, c.height}};
  const Eigen::Vector2f centre(c.radius - c.fillet, c.height - c.fillet);
  for (int i = 0; i <= c.fillet_segments; ++i) {
    const float a = 0.5f * float(M_PI) * float(c.fillet_segments - i) / float(c.fillet_segments);
    profile.push_back(centre + c.fillet * Eigen::Vector2f(std::cos(a), std::sin(a)));
  }
  const float inner = c.radius - c.wall;
  profile.insert(profile.end(), {{c.radius, 0.0f}, {inner, 0.0f}, {inner, c.height - c.wall}, {0.0f, c.height - c.wall}});
  return revolve(profile, c.segments);
}

ModelFile readModelOrBuiltin(const std::string& spec, double scale) {
  constexpr std::string_view prefix = "builtin:";
  if (spec.rfind(prefix, 0) != 0) return readModelFile(spec, scale);
  ModelFile file;
  file.is_mesh = true;
  file.mesh = builtinPart(spec.substr(prefix.size()));
  return file;
}

Mesh builtinPart(const std::string& name) {
  if (name == "cap") return makeCap();
  if (name == "sphere") return makeSphere(30.0f, 4);
  if (name == "box") return makeBox({60.0f, 40.0f, 20.0f}, 4);
  throw Error(fmt::format("unknown built-in part '{}' (known: cap, sphere, box)", name));
}

}  // namespace binpose
