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

/// A 200 x 200 grid of points `spacing` mm apart on the plane z = 0.3 x + `depth`, with Gaussian
/// noise of `sigma` mm along z (Box-Muller on a seeded generator).
Points noisyPlane(float sigma, std::uint64_t seed, float spacing = 1.0f, float depth = 500.0f) {
  Rng rng(seed);
  Points points;
  for (int y = 0; y < 200; ++y)
    for (int x = 0; x < 200; ++x) {
      const double u1 = std::max(rng.uniform(), 1e-12), u2 = rng.uniform();
      const auto g = static_cast<float>(std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2));
      points.emplace_back(spacing * float(x), spacing * float(y), 0.3f * spacing * float(x) + depth + sigma * g);
    }
  return points;
}

NoiseEstimate measured(const Points& points, float far_limit = 0.0f) {
  const PointGrid grid(points);
  std::vector<std::uint32_t> all(points.size());
  std::iota(all.begin(), all.end(), 0u);
  return estimateNoise(points, all, [&](std::uint32_t i, std::size_t k, std::uint32_t* idx) {
    float d2[32];
    return grid.knn(points[i], k, idx, d2);
  }, Vec3::Zero(), far_limit);
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
// tolerances (a symmetric part's angles only where the normals stay rough), and never lowers a
// value the user set higher.
// The spacing is measured in each fit's plane, to the fourth nearest point: on a grid tilted by
// 17 degrees, the wider of its two spacings (3.13 mm along the tilt, 3 mm across), whatever the
// noise along the line of sight.
TEST(Noise, SpacingIsMeasuredAlongTheSurface) {
  for (const float sigma : {0.0f, 0.3f, 1.0f}) {
    const NoiseEstimate n = measured(noisyPlane(sigma, 11, 3.0f));
    ASSERT_GT(n.samples, 200);
    EXPECT_GT(n.spacing, 2.9f) << sigma;
    EXPECT_LT(n.spacing, 3.5f) << sigma;
  }
  const NoiseEstimate fine = measured(noisyPlane(0.1f, 11, 1.0f));
  EXPECT_GT(fine.spacing, 0.95f);
  EXPECT_LT(fine.spacing, 1.2f);
}

TEST(Noise, OnlyANoisyScanRaisesTheValues) {
  const StageSettings p = stageSettings(defaultPreset(), 60.0f);
  const StageSettings clean = adaptedToNoise(p, {0.05f, 1.5f, 256});
  EXPECT_EQ(clean.k_normals, p.k_normals);
  EXPECT_EQ(clean.e_gmax, p.e_gmax);
  EXPECT_EQ(clean.verify_tolerance, p.verify_tolerance);
  EXPECT_EQ(clean.plane_tolerance, p.plane_tolerance);
  EXPECT_EQ(clean.revolution_angle_tolerance, p.revolution_angle_tolerance);
  EXPECT_EQ(clean.report_score, p.report_score);
  EXPECT_EQ(clean.plane_max_angle, p.plane_max_angle);
  const StageSettings mild = adaptedToNoise(p, {0.24f, 2.0f, 256});  // tilt 0.12: k raised, angles kept
  EXPECT_GT(mild.k_normals, p.k_normals);
  EXPECT_EQ(mild.revolution_angle_tolerance, p.revolution_angle_tolerance);
  EXPECT_EQ(mild.many_faces_outline_share, p.many_faces_outline_share);
  EXPECT_GT(p.many_faces_outline_share, p.max_outline_share);
  const StageSettings noisy = adaptedToNoise(p, {1.0f, 2.0f, 256});
  EXPECT_EQ(noisy.revolution_angle_tolerance, 20.0f);  // tilt 0.5: rough normals
  EXPECT_EQ(noisy.many_faces_outline_share, p.max_outline_share);  // a pose seen by many faces held as one seen by one
  EXPECT_GT(noisy.k_normals, p.k_normals);
  EXPECT_LE(noisy.k_normals, 32);
  EXPECT_GT(noisy.e_gmax, 2.0f);
  EXPECT_GT(noisy.verify_tolerance, p.verify_tolerance);
  EXPECT_GT(noisy.plane_tolerance, 2.0f);
  EXPECT_FLOAT_EQ(noisy.report_score, 0.5f);  // tilt 0.5: only detections scoring 0.5 reported
  EXPECT_NEAR(noisy.plane_max_angle * 180.0f / float(M_PI), 55.0f, 0.1f);  // and the plane search's normal test at 55 degrees
  const StageSettings kinect = adaptedToNoise(p, {0.54f, 2.0f, 256});  // tilt 0.27: a real Kinect frame's
  EXPECT_EQ(kinect.report_score, p.report_score);
  EXPECT_EQ(kinect.plane_max_angle, p.plane_max_angle);
  const StageSettings midway = adaptedToNoise(p, {0.7f, 2.0f, 256});  // tilt 0.35
  EXPECT_GT(midway.report_score, p.min_score);
  EXPECT_LT(midway.report_score, 0.5f);
  EXPECT_GT(midway.plane_max_angle, p.plane_max_angle);
  EXPECT_LT(midway.plane_max_angle * 180.0f / float(M_PI), 55.0f);
  EXPECT_NEAR(adaptedToNoise(p, {0.8f, 2.0f, 256}).plane_max_angle * 180.0f / float(M_PI), 55.0f, 0.1f);  // tilt 0.4
  StageSettings loose = p;
  loose.e_gmax = 10.0f;
  EXPECT_EQ(adaptedToNoise(loose, {1.0f, 2.0f, 256}).e_gmax, 10.0f);
  EXPECT_EQ(adaptedToNoise(p, {1.0f, 2.0f, 0}).k_normals, p.k_normals);  // no estimate: no change
}

// Only a scan that wants more neighbours than the pixel search's 32 fits its normals over a
// radius: 8 sigmas, at most 0.15 of the part's diameter and 8 times the reach of 8 neighbours,
// and only where that reaches past the 32 nearest (twice that reach).
TEST(Noise, OnlyAScanTooNoisyFor32NeighboursFitsNormalsOverARadius) {
  const StageSettings p = stageSettings(defaultPreset(), 60.0f);  // normal_max_radius 9 mm
  EXPECT_EQ(adaptedToNoise(p, {0.05f, 1.5f, 256}).normal_radius, 0.0f);  // clean
  EXPECT_EQ(adaptedToNoise(p, {0.54f, 2.0f, 256}).normal_radius, 0.0f);  // tilt 0.27: 27 neighbours
  EXPECT_FLOAT_EQ(adaptedToNoise(p, {0.8f, 2.0f, 256}).normal_radius, 6.4f);  // tilt 0.4: 8 sigmas
  EXPECT_FLOAT_EQ(adaptedToNoise(p, {1.6f, 3.4f, 256}).normal_radius, 9.0f);  // the part's limit
  const StageSettings tiny = stageSettings(defaultPreset(), 6.0f);  // limit 0.9 mm: within the 32 nearest
  EXPECT_EQ(adaptedToNoise(tiny, {0.8f, 2.0f, 256}).normal_radius, 0.0f);
  const StageSettings large = stageSettings(defaultPreset(), 6000.0f);  // limit 900 mm
  EXPECT_FLOAT_EQ(adaptedToNoise(large, {50.0f, 5.0f, 256}).normal_radius, 40.0f);  // 8 reaches
}

// The plane search's fit band: 3 sigma where that is at most half the plane tolerance (1.5 mm for
// a 60 mm part, raised to 2.3 sigma on a noisy scan), else none.
TEST(Noise, OnlyAScanQuietUnderThePlaneToleranceGetsAPlaneFitBand) {
  const StageSettings p = stageSettings(defaultPreset(), 60.0f);
  EXPECT_FLOAT_EQ(adaptedToNoise(p, {0.1f, 1.5f, 256}).plane_fit_band, 0.3f);   // clean: 0.3 of 1.5 mm
  EXPECT_FLOAT_EQ(adaptedToNoise(p, {0.2f, 1.5f, 256}).plane_fit_band, 0.6f);   // industrial
  EXPECT_FLOAT_EQ(adaptedToNoise(p, {0.25f, 1.5f, 256}).plane_fit_band, 0.75f);  // half the tolerance
  EXPECT_EQ(adaptedToNoise(p, {0.3f, 1.5f, 256}).plane_fit_band, 0.0f);         // 0.9 mm: over half
  EXPECT_EQ(adaptedToNoise(p, {1.0f, 2.0f, 256}).plane_fit_band, 0.0f);         // tolerance 2.3 mm, band 3 mm
  EXPECT_EQ(adaptedToNoise(p, {0.1f, 1.5f, 0}).plane_fit_band, 0.0f);           // no estimate
  const StageSettings large = stageSettings(defaultPreset(), 120.0f);           // tolerance 3 mm
  EXPECT_FLOAT_EQ(adaptedToNoise(large, {0.5f, 2.0f, 256}).plane_fit_band, 1.5f);
  EXPECT_EQ(adaptedToNoise(large, {0.94f, 2.0f, 256}).plane_fit_band, 0.0f);    // a Kinect frame's 0.94 mm
}

// Bands of ranges, each 1.25 times the one before: the first judged band (12 fits or more) noisier
// than the limit and three times noisier than the least noisy band nearer than it starts what is
// left out. A noisy band nearer than every quieter one, or one of few fits, is kept.
TEST(Noise, FarNoisyRangeStartsAtTheFirstFarNoisyBand) {
  const auto band = [](std::vector<NoiseSample>& s, float from, float to, float sigma, int fits = 30) {
    for (int i = 0; i < fits; ++i) s.push_back({from + (to - from) * float(i) / float(fits), sigma});
  };
  std::vector<NoiseSample> room;  // a bin at 0.8-1.2 m, the room's wall at 2.5-3 m
  band(room, 800, 1000, 1.0f);
  band(room, 1000, 1200, 1.4f);
  band(room, 2500, 3000, 6.0f);
  EXPECT_EQ(farNoisyRange(room, 2.0f), 2500.0f);
  EXPECT_EQ(farNoisyRange(room, 7.0f), INFINITY);  // noisy, but within what the part allows
  EXPECT_EQ(farNoisyRange(room, 0.0f), INFINITY);  // off
  EXPECT_EQ(farNoisyRange(room, 1.2f), 2500.0f);   // 1.4 is over the limit but not 3 x 1.0
  std::vector<NoiseSample> near_noisy;  // the noisy band is the nearest
  band(near_noisy, 500, 600, 6.0f);
  band(near_noisy, 800, 1000, 1.0f);
  EXPECT_EQ(farNoisyRange(near_noisy, 2.0f), INFINITY);
  std::vector<NoiseSample> few;  // five fits do not judge a band
  band(few, 800, 1000, 1.0f);
  band(few, 2500, 3000, 6.0f, 5);
  EXPECT_EQ(farNoisyRange(few, 2.0f), INFINITY);
  EXPECT_EQ(farNoisyRange({}, 2.0f), INFINITY);
}

// A clean plane 0.5 m away and a rough one 2.5 m away (3 mm noise, 5 mm apart), as many points
// each: measured together the median lies above the near plane's; with a limit, the far plane is
// left out from a range between them and the noise is the near plane's.
TEST(Noise, FarNoisyPlaneIsLeftOutOfTheEstimate) {
  Points points = noisyPlane(0.2f, 7);
  for (const Vec3& q : noisyPlane(3.0f, 8, 5.0f, 2500.0f)) points.push_back(q);
  const NoiseEstimate mixed = measured(points), apart = measured(points, 1.2f);
  EXPECT_TRUE(std::isinf(mixed.far_range));
  ASSERT_TRUE(std::isfinite(apart.far_range));
  EXPECT_GT(apart.far_range, 650.0f);  // the near plane lies within 500-630 mm of the origin
  EXPECT_LT(apart.far_range, 2520.0f);  // the far plane's nearest points, with their noise
  EXPECT_GT(apart.sigma, 0.15f);
  EXPECT_LT(apart.sigma, 0.21f);
  EXPECT_GT(mixed.sigma, 1.2f * apart.sigma);
  EXPECT_GT(apart.samples, 100);
  EXPECT_LT(apart.samples, mixed.samples);
}
