// Plane-fit normals (thesis 5.2.2) and model normals from faces (chapter 6).
#include <binpose/features.hpp>
#include <binpose/geometry.hpp>
#include <binpose/model.hpp>
#include <binpose/normals.hpp>
#include <binpose/shapes.hpp>

#include "test_util.hpp"

#include <cmath>
#include <cstring>
#include <iostream>
#include <random>

using namespace binpose;
using binpose::test::deg;

TEST(Normals, PlaneFitOfNoisyTiltedPlane) {
  const Vec3 n_true = Vec3(1, 2, 3).normalized();
  const Vec3 u = n_true.unitOrthogonal(), v = n_true.cross(u);
  Rng rng(1);
  Points pts;
  for (int i = 0; i < 200; ++i)
    pts.push_back(Vec3(5, 5, 5) + float(20 * rng.uniform() - 10) * u + float(20 * rng.uniform() - 10) * v +
                  float(0.02 * (rng.uniform() - 0.5)) * n_true);
  Vec3 n;
  ASSERT_TRUE(fitPlaneNormal(pts, n));
  EXPECT_LT(deg(std::acos(std::min(1.0f, std::abs(n.dot(n_true))))), 0.2);
}

TEST(Normals, DegenerateNeighbourhoodsAreRefused) {
  Vec3 n;
  EXPECT_FALSE(fitPlaneNormal({{0, 0, 0}, {1, 0, 0}}, n));  // too few
  EXPECT_FALSE(fitPlaneNormal({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}}, n));  // collinear
  EXPECT_FALSE(fitPlaneNormal({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {NAN, 0, 0}}, n));  // NaN
  EXPECT_FALSE(fitPlaneNormal({{1, 1, 1}, {1, 1, 1}, {1, 1, 1}}, n));  // one point thrice
}

TEST(Normals, EstimatedSphereNormalsFaceTheSensor) {
  // Dense points on a sphere of radius 30 around (0, 0, 500), viewed from the origin.
  const Vec3 centre(0, 0, 500);
  Rng rng(2);
  Points cloud;
  for (int i = 0; i < 40000; ++i) {
    Vec3 d(float(rng.uniform() - 0.5), float(rng.uniform() - 0.5), float(rng.uniform() - 0.5));
    if (!normalizeSafe(d)) continue;
    cloud.push_back(centre + 30 * d);
  }
  const Points queries(cloud.begin(), cloud.begin() + 2000);
  const Points normals = estimateNormals(cloud, queries, 6, Vec3::Zero());
  double sum = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    ASSERT_NEAR(normals[i].norm(), 1.0f, 1e-4);
    EXPECT_GT(normals[i].dot(-queries[i]), 0.0f) << "normal must face the sensor at the origin";
    const Vec3 radial = (queries[i] - centre).normalized();
    sum += deg(std::acos(std::min(1.0f, std::abs(normals[i].dot(radial)))));
  }
  EXPECT_LT(sum / queries.size(), 3.0);  // mean error of a 6-neighbour fit on a 30 mm sphere
}

// A noisy depth sensor's sphere (1.5 mm of noise along the ray, points 1.5 mm apart): 32
// nearest neighbours reach about 5 mm, every point within 12 mm averages four times as many
// over a lever arm twice as long, and the normals come out closer to the radial direction.
TEST(Normals, ARadiusWiderThanTheNearestNeighboursSmoothsNoise) {
  const Vec3 centre(0, 0, 800);
  constexpr float kRadius = 60.0f, kSpacing = 1.5f, kNoise = 1.5f;
  Rng rng(3);
  Points cloud;
  for (float x = -40; x <= 40; x += kSpacing)
    for (float y = -40; y <= 40; y += kSpacing) {
      const float z = centre.z() - std::sqrt(kRadius * kRadius - x * x - y * y);
      const Vec3 p(x, y, z);
      cloud.push_back(p + kNoise * rng.gaussian() * p.normalized());  // noise along the ray
    }
  std::vector<std::uint32_t> chosen;
  for (std::uint32_t i = 0; i < cloud.size(); i += 37) chosen.push_back(i);
  const PointGrid grid(cloud);
  Points queries;
  for (const auto i : chosen) queries.push_back(cloud[i]);
  const Points nearest = estimateNormals(grid, cloud, queries, 32, Vec3::Zero());
  const Points wide = radiusNormals(grid, cloud, chosen, 12.0f, Vec3::Zero());
  const auto meanError = [&](const Points& normals) {
    double sum = 0;
    for (std::size_t k = 0; k < chosen.size(); ++k) {
      EXPECT_GT(normals[k].dot(-queries[k]), 0.0f) << "normal must face the sensor at the origin";
      sum += deg(std::acos(std::min(1.0f, normals[k].dot((queries[k] - centre).normalized()))));
    }
    return sum / static_cast<double>(chosen.size());
  };
  const double e_nearest = meanError(nearest), e_wide = meanError(wide);
  std::printf("mean normal error: 32 nearest %.1f deg, within 12 mm %.1f deg\n", e_nearest, e_wide);
  EXPECT_LT(e_wide, 0.5 * e_nearest);
  EXPECT_LT(e_wide, 6.0);
}

TEST(Normals, MeshModelNormalsOfSphereAreRadial) {
  ModelParams params;
  const OrientedModel model = prepareModel(makeSphere(30, 4), params);
  ASSERT_NEAR(double(model.points.size()), 4000.0, 40.0);
  double sum = 0, worst = 0;
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    const double err = deg(std::acos(std::clamp(model.normals[i].dot(model.points[i].normalized()), -1.0f, 1.0f)));
    sum += err;
    worst = std::max(worst, err);
  }
  EXPECT_LT(sum / model.points.size(), 0.3);  // smooth interpolated normals, not facets
  EXPECT_LT(worst, 1.5);                      // outward everywhere (an inward one would be 180)
  EXPECT_NEAR(model.diameter, 60.0f, 0.5f);
}

TEST(Normals, MeshModelNormalsOfBoxAreFaceAxes) {
  const Vec3 size(60, 40, 20);
  ModelParams params;
  params.num_points = 2000;
  const OrientedModel model = prepareModel(makeBox(size, 3), params);
  for (std::size_t i = 0; i < model.points.size(); ++i) {
    const Vec3& p = model.points[i];
    int axis = 0;  // the face the sample lies on
    for (int a = 1; a < 3; ++a)
      if (std::abs(std::abs(p[a]) - size[a] / 2) < std::abs(std::abs(p[axis]) - size[axis] / 2)) axis = a;
    Vec3 expected = Vec3::Zero();
    expected[axis] = p[axis] > 0 ? 1.0f : -1.0f;
    EXPECT_LT(deg(angleBetween(model.normals[i], expected)), 0.01) << "sample " << i << " at " << p.transpose();
  }
}

TEST(Normals, InwardWoundMeshStillGetsOutwardNormals) {
  Mesh sphere = makeSphere(20, 3);
  for (auto& f : sphere.faces) std::swap(f[1], f[2]);  // wind every face the wrong way
  ModelParams params;
  params.num_points = 1000;
  const OrientedModel model = prepareModel(sphere, params);
  for (std::size_t i = 0; i < model.points.size(); ++i) EXPECT_GT(model.normals[i].dot(model.points[i]), 0.0f);
}

namespace {

/// W = Q^T Q about the centroid of `points` (eq. 33-35), in double.
Eigen::Matrix3d scatterOf(const Points& points) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const Vec3& p : points) c += p.cast<double>();
  c /= static_cast<double>(points.size());
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
  for (const Vec3& p : points) {
    const Eigen::Vector3d d = p.cast<double>() - c;
    W += d * d.transpose();
  }
  return W;
}

}  // namespace

// The closed-form eigenvector answers only where it gives the iterative solver's very floats
// (up to the sign): on neighbourhoods like a scan's, tilted or lying flat on an axis (exact
// zeros), noisy or not, nearly collinear, in the depth image's steps.
TEST(Normals, ClosedFormGivesTheSolversFloats) {
  std::mt19937 rng(20261125);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  const float noises[] = {0.0f, 1e-6f, 1e-3f, 0.05f, 0.5f};
  int cases = 0, closed = 0, refused = 0;
  for (int c = 0; c < 60000; ++c) {
    const int kind = c % 5;
    Vec3 normal(unit(rng), unit(rng), unit(rng));
    if (kind == 1) normal = Vec3::Unit(c / 5 % 3);                   // a floor or wall on an axis
    if (kind == 2) normal = (Vec3::Unit(c / 5 % 3) + 1e-6f * normal).eval();  // nearly on one
    if (!normalizeSafe(normal)) continue;
    const Vec3 u = normal.unitOrthogonal(), v = normal.cross(u);
    const Vec3 centre(200.0f * unit(rng), 200.0f * unit(rng), 600.0f + 200.0f * unit(rng));
    const float noise = noises[(c / 5) % 5];
    Points points;
    for (int j = 0; j < 8; ++j) {
      // 3: nearly a line, or a line, or one point repeated.
      const float width = kind != 3 ? 2.0f : (c / 5) % 3 == 0 ? 1e-4f : 0.0f;
      const float a = kind == 3 && (c / 5) % 3 == 2 ? 0.0f : 2.0f * unit(rng), b = width * unit(rng);
      Vec3 p = centre + a * u + b * v + noise * gauss(rng) * normal;
      if (kind == 1) p[c / 5 % 3] = centre[c / 5 % 3];  // exactly flat
      if (kind == 4) p = (p * 8.0f).array().round().matrix() / 8.0f;  // quantized, as depth steps
      points.push_back(p);
    }
    const Eigen::Matrix3d W = scatterOf(points);
    Vec3 fast = Vec3::Zero(), slow = Vec3::Zero();
    bool answered = false;
    const bool ok_fast = detail::scatterNormal(W, fast, true, &answered);
    const bool ok_slow = detail::scatterNormal(W, slow, false);
    ++cases;
    closed += answered;
    refused += !ok_slow;
    ASSERT_EQ(ok_fast, ok_slow) << "case " << c;
    if (!ok_slow) continue;
    const Vec3 flipped = -fast;
    ASSERT_TRUE(std::memcmp(fast.data(), slow.data(), sizeof(Vec3)) == 0 ||
                std::memcmp(flipped.data(), slow.data(), sizeof(Vec3)) == 0)
        << "case " << c << " kind " << kind << ": " << fast.transpose() << " against " << slow.transpose();
  }
  std::cout << cases << " cases: " << closed << " answered in closed form, " << refused << " degenerate\n";
  EXPECT_GT(closed, cases / 2);  // the closed form answers most of them
  EXPECT_GT(refused, 0);         // and degenerate ones came up
}
