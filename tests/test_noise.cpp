// The scan's noise measured on the scan, and what it raises.
#include <binpose/geometry.hpp>
#include <binpose/params.hpp>
#include <binpose/point_grid.hpp>

#include "noise.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

using namespace binpose;

namespace {

/// A 200 x 200 grid of points 1 mm apart on the plane z = 0.3 x + 500, with Gaussian noise of
/// `sigma` mm along z (Box-Muller on a seeded generator).
Points noisyPlane(float sigma, std::uint64_t seed) {
  Rng rng(seed);
  Points points;
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) {
      const double u1 = std::max(rng.uniform(), 1e-12), u2 = rng.uniform();
      const auto g = static_cast<float>(std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2));
      points.emplace_back(float(x), float(y), 0.3f * float(x) + 500.0f + sigma * g);
    }
  return points;
}

NoiseEstimate measured(const Points& points) {
  const PointGrid grid(points);
  std::vector<std::uint32_t> all(points.size());
  std::iota(all.begin(), all.end(), 0u);
  return estimateNoise(points, all, [&](std::uint32_t i, std::size_t k, std::uint32_t* idx) {
    float d2[32];
    return grid.knn(points[i], k, idx, d2);
  });
}

}  // namespace

// The residual of a 24-point plane fit over sqrt(k - 3) estimates the noise: its median over
// the samples lies a little under sigma (the median of a chi with 21 degrees of freedom over
// sqrt(21) is 0.98), and the noise along z of a plane tilted by 17 degrees is 0.96 sigma across
// it. Noise as large as the spacing reads low: the nearest points in space are those whose noise
// is like the point's own. The reach is the 8th neighbour's.
TEST(Noise, PlaneFitResidualsMeasureTheNoise) {
  for (const float sigma : {0.1f, 0.5f}) {
    const NoiseEstimate n = measured(noisyPlane(sigma, 7));
    ASSERT_GT(n.samples, 200);
    EXPECT_GT(n.sigma, 0.75f * sigma) << sigma;
    EXPECT_LT(n.sigma, 1.05f * sigma) << sigma;
    EXPECT_GT(n.reach, 1.0f);  // 8 neighbours on a 1 mm grid: the farthest about 1.4 mm away
    EXPECT_LT(n.reach, 2.5f);
  }
  const NoiseEstimate rough = measured(noisyPlane(1.5f, 7));
  EXPECT_GT(rough.sigma, 0.4f * 1.5f);
  EXPECT_LT(rough.sigma, 1.5f);
  EXPECT_EQ(measured({}).samples, 0);
}

// A clean scan keeps every value; a noisy one raises the normals' k (capped), e_gmax and the
// tolerances, and never lowers a value the user set higher.
TEST(Noise, OnlyANoisyScanRaisesTheValues) {
  const StageSettings p = stageSettings(defaultPreset(), 60.0f);
  const StageSettings clean = adaptedToNoise(p, {0.05f, 1.5f, 256});
  EXPECT_EQ(clean.k_normals, p.k_normals);
  EXPECT_EQ(clean.e_gmax, p.e_gmax);
  EXPECT_EQ(clean.verify_tolerance, p.verify_tolerance);
  EXPECT_EQ(clean.plane_tolerance, p.plane_tolerance);
  const StageSettings noisy = adaptedToNoise(p, {1.0f, 2.0f, 256});
  EXPECT_GT(noisy.k_normals, p.k_normals);
  EXPECT_LE(noisy.k_normals, 32);
  EXPECT_GT(noisy.e_gmax, 2.0f);
  EXPECT_GT(noisy.verify_tolerance, p.verify_tolerance);
  EXPECT_GT(noisy.plane_tolerance, 2.0f);
  StageSettings loose = p;
  loose.e_gmax = 10.0f;
  EXPECT_EQ(adaptedToNoise(loose, {1.0f, 2.0f, 256}).e_gmax, 10.0f);
  EXPECT_EQ(adaptedToNoise(p, {1.0f, 2.0f, 0}).k_normals, p.k_normals);  // no estimate: no change
}
