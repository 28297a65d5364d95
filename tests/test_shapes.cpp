// The built-in parts: closed meshes with the analytic area and outward model normals.
#include <binpose/features.hpp>
#include <binpose/model.hpp>
#include <binpose/sampling.hpp>
#include <binpose/shapes.hpp>

#include "test_util.hpp"

#include <cmath>
#include <map>

using namespace binpose;
using binpose::test::deg;

namespace {
/// Every undirected edge is shared by exactly two faces, used once in each direction.
bool closedAndConsistent(const Mesh& m) {
  std::map<std::pair<int, int>, int> directed;
  for (const auto& f : m.faces)
    for (int k = 0; k < 3; ++k) ++directed[{f[k], f[(k + 1) % 3]}];
  for (const auto& [edge, count] : directed)
    if (count != 1 || directed.count({edge.second, edge.first}) != 1) return false;
  return true;
}
}  // namespace

TEST(Shapes, BuiltinPartsAreClosed) {
  for (const char* name : {"cap", "sphere", "box"}) EXPECT_TRUE(closedAndConsistent(builtinPart(name))) << name;
  EXPECT_THROW(builtinPart("teapot"), Error);
  CapParams bad;
  bad.wall = 20;
  EXPECT_THROW(makeCap(bad), Error);
}

TEST(Shapes, CapAreaIsAnalytic) {
  // Default cap: R 30, H 20, wall 2, fillet 4. Outer top disk, quarter-torus fillet, outer wall,
  // rim annulus, inner wall, inner top.
  const double pi = M_PI;
  const double analytic = pi * 26 * 26 + 8 * pi * (26 * pi / 2 + 4) + 2 * pi * 30 * 16 + pi * (30 * 30 - 28 * 28) +
                          2 * pi * 28 * 18 + pi * 28 * 28;
  EXPECT_NEAR(meshArea(makeCap()), analytic, 0.005 * analytic);
}

TEST(Shapes, CapModelNormalsOnFlatAndCylindricalRegions) {
  const OrientedModel model = prepareModel(makeCap(), ModelParams{});
  int checked = 0;
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    const Vec3& p = model.points[i];
    const float r = std::hypot(p.x(), p.y());
    Vec3 expected = Vec3::Zero();
    if (std::abs(p.z() - 20) < 1e-3f && r < 25.5f) expected = Vec3(0, 0, 1);  // outer top
    else if (std::abs(p.z() - 18) < 1e-3f && r < 27.5f) expected = Vec3(0, 0, -1);  // inner top faces the cavity
    else if (std::abs(r - 30) < 0.1f && p.z() > 0.5f && p.z() < 15.5f) expected = Vec3(p.x(), p.y(), 0).normalized();
    else if (std::abs(r - 28) < 0.1f && p.z() > 0.5f && p.z() < 17.5f) expected = -Vec3(p.x(), p.y(), 0).normalized();
    else continue;
    ++checked;
    EXPECT_LT(deg(angleBetween(model.normals[i], expected)), 2.0) << "point " << p.transpose();
  }
  EXPECT_GT(checked, 2500);
}
