// A depth image's nearest neighbours from its pixel neighbours, against brute force.
#include <algorithm>
#include <binpose/geometry.hpp>
#include <binpose/io.hpp>
#include <binpose/normals.hpp>
#include <binpose/pixel_neighbours.hpp>
#include <binpose/planes.hpp>
#include <binpose/point_grid.hpp>
#include <binpose/scene.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>

#include "test_util.hpp"

#include <cmath>

using namespace binpose;

namespace {

/// Four caps in the bin, lying flat, tilted and on edge: facing and oblique surfaces, the bin's
/// walls seen at a grazing angle and depth edges, as the default sensor sees them.
SimulatedScene capsInBin() {
  const Mesh cap = makeCap();
  std::vector<Pose> world;
  const float tilts[] = {0, 35, 70, 90};
  for (int c = 0; c < 4; ++c) {
    Pose p = Pose::Identity();
    p.linear() = Eigen::AngleAxisf(tilts[c] * float(M_PI) / 180, Vec3(1, float(c), 0).normalized()).toRotationMatrix();
    p.translation() = Vec3(-50.0f + 35.0f * float(c), 20.0f * float(c % 2) - 10.0f, 20);
    world.push_back(p);
  }
  return renderBin(cap, world, BinParams{}, SensorParams{}, 3);
}

/// knn() of every `step`-th point against brute force wherever it answers: the same indices
/// and squared distances in the same order. Returns how many it answered.
std::size_t answeredAsBruteForce(const PointCloud& cloud, std::size_t k, std::size_t step, std::size_t& asked) {
  const PixelNeighbours pixels(cloud);
  EXPECT_TRUE(pixels.usable());
  std::vector<std::uint32_t> idx(k);
  std::vector<float> d2(k);
  std::size_t answered = 0;
  asked = 0;
  for (std::size_t i = 0; i < cloud.size(); i += step) {
    ++asked;
    if (!pixels.knn(static_cast<std::uint32_t>(i), k, idx.data(), d2.data())) continue;
    ++answered;
    const auto truth = test::bruteKnn(cloud.points, cloud.points[i], k);
    for (std::size_t j = 0; j < k; ++j) {
      EXPECT_EQ(idx[j], truth[j].second) << "point " << i << " rank " << j;
      EXPECT_EQ(d2[j], truth[j].first) << "point " << i << " rank " << j;
    }
  }
  return answered;
}

}  // namespace

TEST(PixelNeighbours, BinScanAnswersAreTheNearestOfTheWholeCloud) {
  const SimulatedScene scene = capsInBin();
  ASSERT_GT(scene.cloud.size(), 50000u);
  for (const std::size_t k : {3u, 6u, 8u, 20u}) {  // 6 and 8 (k_normals) have their own code, the others share one
    std::size_t asked = 0;
    const std::size_t answered = answeredAsBruteForce(scene.cloud, k, 211, asked);
    // Most points are answered from their pixels (the grazing walls from 9 x 9 pixels).
    if (k <= 8) EXPECT_GT(answered, asked * 9 / 10) << "k " << k;
    else EXPECT_GT(answered, asked / 4) << "k " << k;
  }
  // More than 32 neighbours are left to the grid.
  std::uint32_t idx[33];
  float d2[33];
  EXPECT_FALSE(PixelNeighbours(scene.cloud).knn(0, 33, idx, d2));
}

// The nearest scan point of any point (ICP's posed model points): near the scan's surface, off
// it, and far from it, under limits from half a millimetre to 8 mm. Each answer proved from the
// pixels is the whole cloud's (brute force): the same point and squared distance, or none
// within the limit with a clearance that holds; the rest is left to the grid.
TEST(PixelNeighbours, NearestOfAnyPointIsTheWholeCloudsOrLeftToTheGrid) {
  const SimulatedScene scene = capsInBin();
  const PixelNeighbours pixels(scene.cloud);
  ASSERT_TRUE(pixels.usable());
  using Proof = PixelNeighbours::Proof;
  Rng rng(11);
  std::size_t asked = 0, found = 0, none = 0;
  for (std::size_t i = 0; i < scene.cloud.size(); i += 397)
    for (const float off : {0.2f, 1.0f, 3.0f, 12.0f}) {
      const Vec3 dir = Vec3(rng.uniform() - 0.5f, rng.uniform() - 0.5f, rng.uniform() - 0.5f).normalized();
      const Vec3 q = scene.cloud.points[i] + off * dir;
      const auto truth = test::bruteKnn(scene.cloud.points, q, 1).front();
      for (const float limit : {0.5f, 2.0f, 8.0f}) {
        ++asked;
        std::uint32_t index = 0;
        float d2 = 0, clearance = 0;
        const Proof proof = pixels.nearest(q, limit * limit, index, d2, &clearance);
        if (proof == Proof::kFound) {
          ++found;
          EXPECT_EQ(index, truth.second) << i << " " << off << " " << limit;
          EXPECT_EQ(d2, truth.first) << i << " " << off << " " << limit;
          EXPECT_LE(d2, limit * limit);
        } else if (proof == Proof::kNone) {
          ++none;
          EXPECT_GT(truth.first, limit * limit) << i << " " << off << " " << limit;
          EXPECT_GE(clearance, limit);
          EXPECT_LE(clearance * clearance, truth.first * 1.0001f);  // no point nearer than the clearance
        }
      }
    }
  EXPECT_GT(found, asked / 3);
  EXPECT_GT(none, asked / 10);
  EXPECT_GT(found + none, asked * 3 / 4);
  // Behind the camera, and outside the image: the grid's.
  std::uint32_t index = 0;
  float d2 = 0;
  EXPECT_EQ(pixels.nearest(Vec3(0, 0, -100), 4.0f, index, d2), Proof::kUnknown);
  EXPECT_EQ(pixels.nearest(Vec3(1e4f, 0, 100), 4.0f, index, d2), Proof::kUnknown);
}

TEST(PixelNeighbours, NearestBeyondTheWindowAreLeftToTheGrid) {
  // A surface 30 mm deeper at each column: a point's nearest are in its own column, about 0.7
  // mm a row apart. Its 8 nearest lie within 4 rows, inside the largest window (9 x 9 pixels);
  // the 12 nearest reach 6 rows away, beyond it, and must not be answered. Holes at random.
  const int w = 40, h = 30;
  Intrinsics k;
  k.fx = 550;
  k.fy = 520;
  k.cx = 20;
  k.cy = 15;
  k.depth_scale = 0.1;
  std::vector<std::uint16_t> depth(std::size_t(w) * h);
  Rng rng(4);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u)
      depth[std::size_t(v) * w + u] = rng.uniform() < 0.1 ? 0 : static_cast<std::uint16_t>(4000 + 300 * u + v % 3);
  const PointCloud cloud = depthToCloud(depth, w, h, k);
  std::size_t asked = 0;
  EXPECT_GT(answeredAsBruteForce(cloud, 8, 1, asked), asked / 2);
  EXPECT_EQ(answeredAsBruteForce(cloud, 12, 1, asked), 0u);
}

TEST(PixelNeighbours, OnlyAPinholeImageWithOnePointPerPixelIsUsed) {
  Intrinsics k;
  k.fx = k.fy = 500;
  k.cx = 2;
  k.cy = 2;
  const PointCloud image = depthToCloud(std::vector<std::uint16_t>(25, 500), 5, 5, k);
  EXPECT_TRUE(PixelNeighbours(image).usable());
  PointCloud unknown_camera = image;
  unknown_camera.fx = 0;
  PointCloud pixel_twice = image;
  pixel_twice.pixel[1] = pixel_twice.pixel[0];
  PointCloud behind = image;
  behind.points[3].z() = -1;
  PointCloud not_finite = image;
  not_finite.points[3].x() = NAN;
  PointCloud out_of_order = image;  // two points (and their pixels) swapped
  std::swap(out_of_order.points[5], out_of_order.points[6]);
  std::swap(out_of_order.pixel[5], out_of_order.pixel[6]);
  PointCloud outside = image;
  outside.pixel.back() = 25;
  for (const PointCloud* c : {&unknown_camera, &pixel_twice, &behind, &not_finite, &out_of_order, &outside}) {
    const PixelNeighbours pixels(*c);
    EXPECT_FALSE(pixels.usable());
    std::uint32_t idx[3];
    float d2[3];
    EXPECT_FALSE(pixels.knn(12, 3, idx, d2));
  }
}

TEST(Normals, FromPixelNeighboursTheSameAsFromTheGrid) {
  const SimulatedScene scene = capsInBin();
  const PointGrid grid(scene.cloud.points);
  const PixelNeighbours pixels(scene.cloud);
  std::vector<std::uint32_t> chosen;
  for (std::uint32_t i = 0; i < scene.cloud.size(); i += 7) chosen.push_back(i);
  const Points from_pixels = estimateNormals(grid, &pixels, scene.cloud.points, chosen, 8, Vec3::Zero());
  const Points from_grid = estimateNormals(grid, nullptr, scene.cloud.points, chosen, 8, Vec3::Zero());
  ASSERT_EQ(from_pixels.size(), chosen.size());
  std::size_t missing = 0;
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    EXPECT_EQ(from_pixels[i], from_grid[i]) << "point " << chosen[i];
    missing += from_grid[i].isZero();
  }
  EXPECT_LT(missing, chosen.size() / 100);  // the comparison is of normals, not of zeros
  // In two halves, as the detector runs them (the first before the grid is built): the points the
  // pixels cannot answer for are left zero and listed, then given the grid's normals.
  std::vector<std::uint32_t> deferred;
  Points halves = pixelNormals(pixels, scene.cloud.points, chosen, 8, Vec3::Zero(), deferred);
  EXPECT_GT(deferred.size(), 0u);
  EXPECT_LT(deferred.size(), chosen.size() / 10);
  EXPECT_TRUE(std::is_sorted(deferred.begin(), deferred.end()));
  for (const auto d : deferred) EXPECT_TRUE(halves[d].isZero()) << "point " << chosen[d];
  finishNormals(grid, scene.cloud.points, chosen, deferred, 8, Vec3::Zero(), halves);
  EXPECT_EQ(halves, from_grid);
  // With the grid built while the first half runs: once it is there, the pixels' misses go to it
  // there and then (here from the start: none left over), with the same normals.
  const std::atomic<const PointGrid*> ready{&grid};
  std::vector<std::uint32_t> none_left;
  EXPECT_EQ(pixelNormals(pixels, scene.cloud.points, chosen, 8, Vec3::Zero(), none_left, &ready), from_grid);
  EXPECT_TRUE(none_left.empty());
}

TEST(Normals, PendingFitsGiveTheSameNormalsAndPlanes) {
  // The detector leaves the normals that need the iterative solver pending until the plane
  // search asks for them. Each pending fit gives the normal computed at once; its angle, where
  // settled from the fit alone, is the normal's; and the search finds the same planes with the
  // same normals for the points it keeps, leaving some fits never finished.
  const SimulatedScene scene = capsInBin();
  const Points& cloud = scene.cloud.points;
  const PointGrid grid(cloud);
  const PixelNeighbours pixels(scene.cloud);
  const std::vector<std::uint32_t> chosen = voxelSubsample(cloud, 2.5f);
  const Vec3 view = Vec3::Zero();
  std::vector<std::uint32_t> deferred;
  Points eager = pixelNormals(pixels, cloud, chosen, 8, view, deferred);
  finishNormals(grid, cloud, chosen, deferred, 8, view, eager);
  std::vector<PendingFit> fits;
  Points late = pixelNormals(pixels, cloud, chosen, 8, view, deferred, nullptr, &fits);
  finishNormals(grid, cloud, chosen, deferred, 8, view, late, &fits);
  ASSERT_EQ(fits.size(), chosen.size());
  const float min_cos = std::cos(PlaneParams{}.max_angle);
  std::size_t pending = 0, settled = 0;
  for (std::size_t i = 0; i < chosen.size(); ++i) {
    if (!std::isnan(late[i].x())) {
      EXPECT_EQ(late[i], eager[i]) << "point " << chosen[i];
      continue;
    }
    ++pending;
    Vec3 n;
    ASSERT_TRUE(finishPending(fits[i], cloud[chosen[i]], view, n));
    EXPECT_EQ(n, eager[i]) << "point " << chosen[i];
    for (const Vec3& m : {Vec3(Vec3::UnitX()), Vec3(Vec3::UnitY()), Vec3(Vec3::UnitZ()), Vec3(Vec3(1, 1, 4).normalized()),
                          Vec3(Vec3(-2, 1, 1).normalized())}) {
      const int aligned = pendingAligned(fits[i], m, min_cos);
      if (aligned < 0) continue;
      ++settled;
      EXPECT_EQ(aligned == 1, std::abs(m.dot(eager[i])) >= min_cos) << "point " << chosen[i];
    }
  }
  EXPECT_GT(pending, chosen.size() / 20);
  EXPECT_GT(settled, pending);
  // The plane search on both.
  const PreparedScene all = orientedScene(cloud, chosen, eager);
  PreparedScene some = orientedScene(cloud, chosen, late);
  ASSERT_EQ(some.points.size(), all.points.size());
  std::vector<char> unfinished(some.points.size(), 0);
  std::vector<std::uint32_t> place(some.points.size());
  for (std::size_t j = 0, i = 0; j < some.points.size(); ++j) {
    while (chosen[i] != some.scan_index[j]) ++i;
    place[j] = static_cast<std::uint32_t>(i);
    unfinished[j] = std::isnan(some.normals[j].x());
  }
  LateNormals source;
  source.pending = &unfinished;
  source.finish = [&](std::span<const std::uint32_t> which) {
    for (const auto j : which)
      if (unfinished[j]) {
        unfinished[j] = 0;
        ASSERT_TRUE(finishPending(fits[place[j]], some.points[j], view, some.normals[j]));
      }
  };
  source.aligned = [&](std::uint32_t j, const Vec3& m, float c) { return pendingAligned(fits[place[j]], m, c); };
  const float density = 1.0f / (2.5f * 2.5f);
  std::vector<Plane> planes_all, planes_some;
  const std::vector<char> flat = largePlanes(all.points, all.normals, density, PlaneParams{}, &planes_all);
  EXPECT_EQ(largePlanes(some.points, some.normals, density, PlaneParams{}, &planes_some, &source), flat);
  ASSERT_EQ(planes_some.size(), planes_all.size());
  EXPECT_GE(planes_all.size(), 1u);
  std::vector<std::uint32_t> kept;  // their normals computed after the search, as the detector does
  for (std::uint32_t j = 0; j < flat.size(); ++j)
    if (!flat[j]) kept.push_back(j);
  source.finish(kept);
  std::size_t never = 0;
  for (std::size_t j = 0; j < flat.size(); ++j) {
    if (unfinished[j]) {
      ++never;
      EXPECT_TRUE(flat[j]);
      continue;
    }
    EXPECT_EQ(some.normals[j], all.normals[j]) << "point " << some.scan_index[j];
  }
  EXPECT_GT(never, 0u);
}
