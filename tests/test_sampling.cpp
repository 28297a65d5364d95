// Poisson-disk sampling (thesis 6.2) and the scene's voxel sub-sampling (5.2.1).
#include <binpose/geometry.hpp>
#include <binpose/sampling.hpp>
#include <binpose/scene.hpp>
#include <binpose/shapes.hpp>

#include "test_util.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

using namespace binpose;

namespace {
Points poolOf(const Mesh& mesh, std::size_t n, std::uint64_t seed) {
  Points pts;
  for (const auto& s : sampleSurfaceUniform(mesh, n, seed)) pts.push_back(s.point);
  return pts;
}

float minPairDistance(const Points& pts) {
  float best = INFINITY;
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (std::size_t j = i + 1; j < pts.size(); ++j) best = std::min(best, (pts[i] - pts[j]).norm());
  return best;
}

float farthestFromSamples(const Points& probes, const Points& samples) {
  float worst = 0;
  for (const Vec3& p : probes) {
    float nearest = INFINITY;
    for (const Vec3& s : samples) nearest = std::min(nearest, (p - s).norm());
    worst = std::max(worst, nearest);
  }
  return worst;
}
}  // namespace

TEST(Sampling, MeshAreaOfBoxAndSphere) {
  EXPECT_NEAR(meshArea(makeBox({60, 40, 20}, 3)), 2 * (60 * 40 + 60 * 20 + 40 * 20), 1e-2);
  // an icosphere inscribed in the sphere: area a little below 4 pi r^2
  const double sphere = meshArea(makeSphere(10, 4));
  EXPECT_LT(sphere, 4 * M_PI * 100);
  EXPECT_GT(sphere, 0.995 * 4 * M_PI * 100);
}

TEST(Sampling, UniformSamplesFollowArea) {
  const Vec3 size(60, 40, 20);
  const Mesh box = makeBox(size, 1);
  const auto samples = sampleSurfaceUniform(box, 60000, 3);
  // Share of samples on the faces normal to x, y, z against the area share.
  double count[3] = {0, 0, 0};
  for (const auto& s : samples)
    for (int a = 0; a < 3; ++a)
      if (std::abs(std::abs(s.point[a]) - size[a] / 2) < 1e-3f) count[a] += 1;
  const double total = 2 * (60 * 40 + 60 * 20 + 40 * 20);
  const double expected[3] = {2 * 40 * 20 / total, 2 * 60 * 20 / total, 2 * 60 * 40 / total};
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(count[a] / samples.size(), expected[a], 0.01) << "axis " << a;
}

TEST(Sampling, PoissonDiskSpacingAndCoverage) {
  const Mesh box = makeBox({60, 40, 20}, 2);
  const Points pool = poolOf(box, 40000, 5);
  const float radius = 2.0f;
  const auto kept = poissonDiskSelect(pool, radius, 9);
  Points samples;
  for (auto i : kept) samples.push_back(pool[i]);
  ASSERT_GT(samples.size(), 100u);
  EXPECT_GE(minPairDistance(samples), radius);  // no two samples closer than the radius
  EXPECT_LE(farthestFromSamples(pool, samples), radius);  // maximal: every candidate is covered
  // and the surface itself is covered: fresh points (another seed) lie near a sample
  EXPECT_LT(farthestFromSamples(poolOf(box, 5000, 77), samples), 1.6f * radius);
}

TEST(Sampling, CountTargetAndDeterminism) {
  const Mesh sphere = makeSphere(30, 4);
  const Points pool = poolOf(sphere, 80000, 1);
  float r1 = 0, r2 = 0;
  const auto a = poissonDiskSelectCount(pool, 4000, 42, &r1);
  const auto b = poissonDiskSelectCount(pool, 4000, 42, &r2);
  EXPECT_NEAR(double(a.size()), 4000.0, 40.0);
  EXPECT_EQ(a, b);
  EXPECT_EQ(r1, r2);
  Points samples;
  for (auto i : a) samples.push_back(pool[i]);
  EXPECT_GE(minPairDistance(samples), r1);
  // the radius of a well-spread set: between a hexagonal packing bound and half of it
  const double area = meshArea(sphere);
  const double hex = std::sqrt(2 * area / (std::sqrt(3.0) * 4000));  // spacing of a perfect hex grid
  EXPECT_LT(r1, hex);
  EXPECT_GT(r1, 0.6 * hex);
  const auto c = poissonDiskSelectCount(pool, 4000, 43);
  EXPECT_NE(a, c);  // the seed matters
}

TEST(Sampling, RejectsBadArguments) {
  const Points pool = poolOf(makeSphere(5, 2), 100, 1);
  EXPECT_THROW(poissonDiskSelectCount(pool, 0, 1), Error);
  EXPECT_THROW(poissonDiskSelect(pool, -1.0f, 1), Error);
  Mesh flat;
  flat.vertices = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  flat.faces = {{0, 1, 2}};
  EXPECT_THROW(sampleSurfaceUniform(flat, 10, 1), Error);
}

namespace {

/// voxelSubsample by its definition: per cube floor(p / voxel), the point nearest the centroid
/// of the cube's points (the lowest index among equals), ascending.
std::vector<std::uint32_t> voxelReference(const Points& points, float voxel) {
  std::map<std::array<long, 3>, std::vector<std::uint32_t>> cubes;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Vec3 c = (points[i] / voxel).array().floor();
    cubes[{long(c.x()), long(c.y()), long(c.z())}].push_back(static_cast<std::uint32_t>(i));
  }
  std::vector<std::uint32_t> kept;
  for (const auto& [key, ids] : cubes) {
    Vec3 centroid = Vec3::Zero();
    for (const auto i : ids) centroid += points[i];
    centroid /= float(ids.size());
    std::uint32_t best = ids[0];
    for (const auto i : ids)
      if ((points[i] - centroid).squaredNorm() < (points[best] - centroid).squaredNorm()) best = i;
    kept.push_back(best);
  }
  std::sort(kept.begin(), kept.end());
  return kept;
}

}  // namespace

TEST(VoxelSubsample, OnePointPerCubeNearestItsCentroid) {
  Rng rng(4);
  Points points;
  for (int i = 0; i < 20000; ++i)  // a noisy bowl, negative coordinates included
    points.emplace_back(float(200 * rng.uniform() - 100), float(150 * rng.uniform() - 75), 0.0f);
  for (Vec3& p : points) p.z() = 400.0f + 0.01f * p.head<2>().squaredNorm() + float(rng.uniform());
  for (const float voxel : {2.0f, 4.0f, 7.5f}) {
    const auto kept = voxelSubsample(points, voxel);
    EXPECT_EQ(kept, voxelReference(points, voxel)) << "voxel " << voxel;
    // A stray point far away (the sparse path, by sorted keys) changes nothing else.
    Points with_stray = points;
    with_stray.emplace_back(3e5f, -3e5f, 3e5f);
    auto expected = kept;
    expected.push_back(static_cast<std::uint32_t>(points.size()));
    EXPECT_EQ(voxelSubsample(with_stray, voxel), expected) << "voxel " << voxel;
    // One beyond 2^20 voxels on an axis, amid the others (the keys' path), and tiny clouds.
    Points with_far = points;
    with_far[points.size() / 2].y() = 3e6f * voxel;
    EXPECT_EQ(voxelSubsample(with_far, voxel), voxelReference(with_far, voxel)) << "voxel " << voxel;
    for (const std::size_t n : {1, 2, 3, 5}) {
      const Points few(points.begin(), points.begin() + static_cast<long>(n));
      EXPECT_EQ(voxelSubsample(few, 100.0f), voxelReference(few, 100.0f)) << n << " points";
    }
  }
}

// The sub-groups of 5.2.3-5.2.4 against a direct reading of their definition: a node every eta
// over the x-y bounds (column by column), each node's group the points within r of it in x-y in
// index order, groups under min_size left out, and the rest ordered closest to the mean size
// first (ties in node order). Wide circles (r > eta), gaps (r < eta), and a radius so small
// against the scene that the cells are wider than r.
TEST(SubGroups, EachNodeHoldsThePointsWithinRadius) {
  Rng rng(9);
  Points points;
  for (int i = 0; i < 3000; ++i)
    points.emplace_back(float(300 * rng.uniform() - 120), float(200 * rng.uniform() + 40), float(50 * rng.uniform()));
  for (int i = 0; i < 300; ++i) points.push_back(points[rng.below(points.size())]);  // duplicates
  Vec3 lo, hi;
  ASSERT_TRUE(bounds(points, lo, hi));
  for (int gx = 0; gx < 7; ++gx)  // points within 0.1 mm of some nodes 40 mm apart
    for (int gy = 0; gy < 5; gy += 1 + gx % 2) points.push_back(lo + Vec3(40.0f * float(gx) + 0.05f, 40.0f * float(gy) + 0.02f, 7.0f));
  struct Case { float eta, r; std::size_t min_size; };
  for (const Case c : {Case{15.0f, 25.0f, 6}, Case{20.0f, 8.0f, 3}, Case{40.0f, 0.1f, 1}, Case{15.0f, 25.0f, 100}}) {
    std::vector<std::vector<std::uint32_t>> expected;
    for (long gx = 0; gx <= long(std::floor((hi.x() - lo.x()) / c.eta)); ++gx)
      for (long gy = 0; gy <= long(std::floor((hi.y() - lo.y()) / c.eta)); ++gy) {
        const Vec3 node = lo + Vec3(float(gx) * c.eta, float(gy) * c.eta, 0.0f);
        std::vector<std::uint32_t> members;
        for (std::uint32_t i = 0; i < points.size(); ++i) {
          const float dx = points[i].x() - node.x(), dy = points[i].y() - node.y();
          if (dx * dx + dy * dy <= c.r * c.r) members.push_back(i);
        }
        if (members.size() >= c.min_size) expected.push_back(members);
      }
    double mean = 0;
    for (const auto& g : expected) mean += double(g.size()) / double(expected.size());
    std::stable_sort(expected.begin(), expected.end(), [&](const auto& a, const auto& b) {
      return std::abs(double(a.size()) - mean) < std::abs(double(b.size()) - mean);
    });
    const auto groups = makeSubGroups(points, c.eta, c.r, c.min_size);
    EXPECT_GT(groups.size(), 3u) << "eta " << c.eta << " r " << c.r;
    EXPECT_EQ(groups, expected) << "eta " << c.eta << " r " << c.r;
  }
}
