// The scan's neighbour grid against brute force.
#include <binpose/geometry.hpp>
#include <binpose/point_grid.hpp>

#include "test_util.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

using namespace binpose;

namespace {

/// A depth-scan-like surface: a wavy sheet on a 1 mm pixel grid (many equal distances) and a
/// random cluster above it.
Points scanLike() {
  Points points;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 80; ++x) points.emplace_back(float(x), float(y), 500.0f + 3.0f * std::sin(0.2f * float(x)));
  Rng rng(5);
  for (int i = 0; i < 500; ++i)
    points.emplace_back(float(40 * rng.uniform()), float(30 * rng.uniform()), float(480 + 10 * rng.uniform()));
  return points;
}

/// A query within `spread` / 2 per axis of a random point of the cloud.
Vec3 queryNear(const Points& points, Rng& rng, float spread) {
  return points[rng.below(points.size())] + spread * Vec3(float(rng.uniform()) - 0.5f, float(rng.uniform()) - 0.5f,
                                                          float(rng.uniform()) - 0.5f);
}

}  // namespace

TEST(PointGrid, KnnEqualsBruteForceTiesIncluded) {
  const Points points = scanLike();
  for (const float cell : {0.0f, 0.7f, 2.0f, 9.0f}) {
    const PointGrid grid(points, cell);
    Rng rng(9);
    for (int t = 0; t < 300; ++t) {
      // On points (exact ties on the pixel grid), near them, and far outside the cloud.
      Vec3 q = points[rng.below(points.size())];
      if (t % 3 == 1) q += Vec3(float(rng.uniform()), float(rng.uniform()), float(rng.uniform()));
      if (t % 3 == 2) q += Vec3(0, 0, -300.0f * float(rng.uniform()) - 50.0f);
      const std::size_t k = 1 + t % 16;  // k_normals (6, the default's 8) and well beyond
      std::uint32_t idx[16];
      float d2[16];
      const std::size_t n = grid.knn(q, k, idx, d2);
      const auto truth = test::bruteKnn(points, q, k);
      ASSERT_EQ(n, truth.size());
      for (std::size_t j = 0; j < n; ++j) {
        EXPECT_EQ(idx[j], truth[j].second) << "cell " << cell << " query " << t << " rank " << j;
        EXPECT_EQ(d2[j], truth[j].first);
      }
    }
  }
}

TEST(PointGrid, NearestWithinEqualsBruteForce) {
  const Points points = scanLike();
  const PointGrid grid(points);
  Rng rng(11);
  int found = 0, missed = 0;
  for (int t = 0; t < 2000; ++t) {
    const Vec3 q = queryNear(points, rng, 4.0f);
    const float gate = 0.25f + 3.0f * float(rng.uniform());
    const auto truth = test::bruteKnn(points, q, 1);
    const bool within = truth[0].first <= gate * gate;
    std::uint32_t j = 0;
    float d2 = 0;
    ASSERT_EQ(grid.nearest(q, gate, j, d2), within) << "query " << t;
    EXPECT_EQ(grid.anyWithin(q, gate), within) << "query " << t;
    if (!within) {
      ++missed;
      continue;
    }
    ++found;
    EXPECT_EQ(j, truth[0].second);
    EXPECT_EQ(d2, truth[0].first);
  }
  EXPECT_GT(found, 500);  // both outcomes were exercised
  EXPECT_GT(missed, 100);
}

TEST(PointGrid, AMissReportsAClearanceFreeOfPoints) {
  // nearest() with a clearance: the same answers as nearest(), whether or not the query missed
  // before; on a miss, no point lies within the clearance, which is at least the gate.
  const Points points = scanLike();
  for (const float cell : {0.0f, 0.7f, 2.0f}) {
    const PointGrid grid(points, cell);
    Rng rng(13);
    int missed = 0, beyond_gate = 0, wider = 0;
    for (int t = 0; t < 1500; ++t) {
      const Vec3 q = queryNear(points, rng, 8.0f);
      const float gate = 0.25f + 3.0f * float(rng.uniform());
      const auto truth = test::bruteKnn(points, q, 1);
      std::uint32_t j0 = 0, j = 0;
      float d0 = 0, d2 = 0;
      const bool found = grid.nearest(q, gate, j0, d0);
      for (const float before : {0.0f, 1.0f}) {  // a first search, and one after a miss
        float clearance = before;
        ASSERT_EQ(grid.nearest(q, gate, j, d2, clearance), found) << "cell " << cell << " query " << t;
        if (found) {
          EXPECT_EQ(j, j0);
          EXPECT_EQ(d2, d0);
          EXPECT_EQ(clearance, 0.0f);
          continue;
        }
        EXPECT_GE(clearance, gate * (1 - 1e-5f)) << "cell " << cell << " query " << t;
        EXPECT_LE(clearance * clearance, truth[0].first * (1 + 1e-5f)) << "cell " << cell << " query " << t;
        missed += before == 0;
        beyond_gate += before == 0 && clearance > 1.2f * gate;
        wider += before == 1 && clearance > 1.45f * gate;
      }
    }
    EXPECT_GT(missed, 200) << "cell " << cell;
    EXPECT_GT(beyond_gate, 50) << "cell " << cell;  // the clearance tells more than the gate
    EXPECT_GT(wider, missed / 2) << "cell " << cell;  // after a miss, the wider box's clearance (1.0: 45-174 of 869)
  }
}

TEST(PointGrid, APointExactlyAtTheGateIsWithin) {
  // Half-way between two pixels of the sheet: the nearest is exactly 0.5 mm away.
  const Points points = scanLike();
  const PointGrid grid(points);
  for (int i = 0; i < 4800; i += 97) {
    const Vec3 q = points[static_cast<std::size_t>(i)] + Vec3(0.5f, 0.0f, 0.0f);
    ASSERT_EQ(test::bruteKnn(points, q, 1)[0].first, 0.25f);
    EXPECT_TRUE(grid.anyWithin(q, 0.5f)) << "point " << i;
    EXPECT_FALSE(grid.anyWithin(q, 0.49f)) << "point " << i;
    std::uint32_t j;
    float d2;
    EXPECT_TRUE(grid.nearest(q, 0.5f, j, d2)) << "point " << i;
  }
}

TEST(PointGrid, NearestWithinAKnownPointsDistanceIsTheNearest) {
  // ICP's query: the distance to one point is known (its pair of the step before), and the
  // nearest lies no farther. Queries on the points (distance 0, ties on the pixel grid), near
  // them and above the sheet; the known point is one of the 12 nearest.
  const Points points = scanLike();
  for (const float cell : {0.0f, 0.7f, 3.0f}) {
    const PointGrid grid(points, cell);
    Rng rng(17);
    int farther = 0;
    for (int t = 0; t < 1000; ++t) {
      Vec3 q = points[rng.below(points.size())];
      if (t % 3 == 1) q += Vec3(float(rng.uniform()), float(rng.uniform()), float(rng.uniform()));
      if (t % 3 == 2) q += Vec3(0, 0, -5.0f * float(rng.uniform()));
      const auto truth = test::bruteKnn(points, q, 12);
      const auto& known = truth[rng.below(truth.size())];
      farther += known.first > truth[0].first;
      std::uint32_t j = 0;
      float d2 = 0;
      ASSERT_TRUE(grid.nearestWithin(q, known.first, j, d2)) << "cell " << cell << " query " << t;
      EXPECT_EQ(j, truth[0].second) << "cell " << cell << " query " << t;
      EXPECT_EQ(d2, truth[0].first);
    }
    EXPECT_GT(farther, 500);  // mostly a known point other than the nearest
  }
}

TEST(PointGrid, WithinRadiusEqualsBruteForce) {
  // Radii on the pixel spacing (points exactly at the radius are out: d^2 < r^2), and radii
  // several cells wide; queries on, near and far from the points.
  const Points points = scanLike();
  for (const float cell : {0.0f, 1.0f, 4.0f}) {
    const PointGrid grid(points, cell);
    Rng rng(13);
    std::vector<std::uint32_t> got;
    std::size_t total = 0;
    for (int t = 0; t < 300; ++t) {
      Vec3 q = points[rng.below(points.size())];
      if (t % 3 == 1) q += Vec3(float(rng.uniform()), float(rng.uniform()), float(rng.uniform()));
      if (t % 3 == 2) q += Vec3(0, 0, -30.0f * float(rng.uniform()));
      const float radius = t % 2 == 0 ? float(1 + t % 4) : 10.0f * float(rng.uniform()) + 0.1f;
      grid.within(q, radius, got);
      std::sort(got.begin(), got.end());
      std::vector<std::uint32_t> truth;
      for (std::uint32_t i = 0; i < points.size(); ++i)
        if ((points[i] - q).squaredNorm() < radius * radius) truth.push_back(i);
      ASSERT_EQ(got, truth) << "cell " << cell << " query " << t << " radius " << radius;
      total += truth.size();
    }
    EXPECT_GT(total, 3000u);  // the queries found something to compare
  }
}

TEST(PointGrid, FewOrBadPointsAreHandled) {
  std::uint32_t idx[4];
  float d2[4];
  const PointGrid empty(Points{});
  EXPECT_EQ(empty.knn(Vec3::Zero(), 3, idx, d2), 0u);
  EXPECT_FALSE(empty.nearest(Vec3::Zero(), 10.0f, idx[0], d2[0]));

  // Non-finite points are never neighbours; fewer points than k gives them all.
  const Points points = {{0, 0, 0}, {NAN, 0, 0}, {1, 0, 0}, {0, INFINITY, 0}, {5, 5, 5}};
  const PointGrid grid(points);
  EXPECT_EQ(grid.size(), 3u);
  ASSERT_EQ(grid.knn(Vec3(0.9f, 0, 0), 4, idx, d2), 3u);
  EXPECT_EQ(idx[0], 2u);
  EXPECT_EQ(idx[1], 0u);
  EXPECT_EQ(idx[2], 4u);
  EXPECT_EQ(grid.knn(Vec3(NAN, 0, 0), 2, idx, d2), 0u);
  EXPECT_FALSE(grid.nearest(Vec3(3, 3, 3), 1.0f, idx[0], d2[0]));
  EXPECT_FALSE(grid.nearest(Vec3(0, 0, 0), NAN, idx[0], d2[0]));

  // All points in one place: one cell, every distance tied.
  const PointGrid same(Points(10, Vec3(1, 2, 3)));
  ASSERT_EQ(same.knn(Vec3(1, 2, 3), 3, idx, d2), 3u);
  EXPECT_EQ(idx[0], 0u);
  EXPECT_EQ(idx[2], 2u);
  EXPECT_EQ(d2[2], 0.0f);
}

TEST(PointGrid, AFarOutlierDoesNotExplodeTheGrid) {
  Points points = scanLike();
  points.emplace_back(1e7f, -1e7f, 1e7f);  // a stray point kilometres away
  const PointGrid grid(points);
  EXPECT_LT(grid.cellSize(), 4.0f);  // sized by the bulk of the points (about 2 spacings), not by the stray one
  std::uint32_t j;
  float d2;
  ASSERT_TRUE(grid.nearest(points[100] + Vec3(0.1f, 0, 0), 1.0f, j, d2));
  EXPECT_EQ(j, 100u);
  std::uint32_t idx[2];
  float dd[2];
  ASSERT_EQ(grid.knn(Vec3(1e7f, -1e7f, 1e7f + 1), 1, idx, dd), 1u);
  EXPECT_EQ(idx[0], points.size() - 1);
}

TEST(PointGrid, PixelSpacingIsTheNeighbourPitchOfADepthImage) {
  // A 100 x 80 depth image of a plane seen head-on at a 0.8 mm pitch, a tenth of its pixels
  // missing (not in the cloud), and a copy whose row pitch is 2 mm: the nearest pixel neighbour
  // lies along the row, so the spacing is the column pitch.
  for (const float row_pitch : {0.8f, 2.0f}) {
    PointCloud cloud;
    cloud.width = 100;
    cloud.height = 80;
    Rng rng(3);
    for (int v = 0; v < cloud.height; ++v)
      for (int u = 0; u < cloud.width; ++u) {
        if (rng.uniform() < 0.1) continue;
        cloud.points.emplace_back(0.8f * float(u), row_pitch * float(v), 500.0f);
        cloud.pixel.push_back(v * cloud.width + u);
      }
    EXPECT_NEAR(pixelSpacing(cloud), 0.8f, 1e-4f) << row_pitch;
    // The grid sized from it answers as the grid that estimates its own cell.
    const PointGrid sized(cloud.points, 2.0f * pixelSpacing(cloud)), estimated(cloud.points);
    std::uint32_t a[8], b[8];
    float da[8], db[8];
    for (std::size_t i = 0; i < cloud.size(); i += 37) {
      ASSERT_EQ(sized.knn(cloud.points[i], 8, a, da), estimated.knn(cloud.points[i], 8, b, db));
      EXPECT_TRUE(std::equal(a, a + 8, b)) << i;
    }
  }
  PointCloud unorganized;
  unorganized.points = scanLike();
  EXPECT_EQ(pixelSpacing(unorganized), 0.0f);  // no pixels: the grid estimates its own cell
}
