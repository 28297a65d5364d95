// Noise shared by neighbouring pixels (correlated_noise.hpp): told from independent noise, and
// thinned out of a depth image until the pixels kept have their own.
#include "correlated_noise.hpp"
#include "stage_settings.hpp"
#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

using namespace binpose;

namespace {

constexpr float kFx = 550.0f;

/// A tilted floor 800 mm away with a dome on it, and 1.3 mm of independent noise per pixel
/// (a structured-light sensor's there), `width` x `height` pixels; no depth in a corner.
std::vector<float> noisyDepths(int width, int height, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 1.3f);
  std::vector<float> depth(static_cast<std::size_t>(width * height));
  for (int v = 0; v < height; ++v)
    for (int u = 0; u < width; ++u) {
      const float du = static_cast<float>(u - width / 2), dv = static_cast<float>(v - height / 2);
      const float dome = std::max(0.0f, 900.0f - du * du - dv * dv) / 30.0f;  // 30 mm high, 30 px wide
      const bool corner = u < width / 8 && v < height / 8;
      depth[static_cast<std::size_t>(v * width + u)] = corner ? 0.0f : 800.0f + 0.2f * du + 0.1f * dv - dome + noise(rng);
    }
  return depth;
}

float at(const std::vector<float>& depth, int width, int u, int v) { return depth[static_cast<std::size_t>(v * width + u)]; }

/// The depths seen by a sensor with twice the pixels each way, each pixel repeating the depth of
/// the one it lies in (a depth image registered to a camera with twice its resolution).
PointCloud repeatedTwice(const std::vector<float>& depth, int width, int height) {
  return test::depthImage(2 * width, 2 * height, 2 * kFx, [&](int u, int v) { return at(depth, width, u / 2, v / 2); });
}

/// ... each pixel the mean of the nearest ones (bilinear): its noise shared with its neighbours.
PointCloud interpolatedTwice(const std::vector<float>& depth, int width, int height) {
  return test::depthImage(2 * width, 2 * height, 2 * kFx, [&](int u, int v) {
    const int u0 = u / 2, v0 = v / 2, u1 = std::min(width - 1, u0 + u % 2), v1 = std::min(height - 1, v0 + v % 2);
    const float a = at(depth, width, u0, v0), b = at(depth, width, u1, v0), c = at(depth, width, u0, v1), d = at(depth, width, u1, v1);
    return a > 0 && b > 0 && c > 0 && d > 0 ? 0.25f * (a + b + c + d) : 0.0f;
  });
}

constexpr int kWidth = 320, kHeight = 240;

}  // namespace

TEST(CorrelatedNoise, IndependentNoiseReadsNegativeSharedNoisePositive) {
  const std::vector<float> depth = noisyDepths(kWidth, kHeight, 7);
  const PixelNoise independent = pixelNoise(test::depthImage(kWidth, kHeight, kFx, [&](int u, int v) { return at(depth, kWidth, u, v); }));
  const PixelNoise repeated = pixelNoise(repeatedTwice(depth, kWidth, kHeight));
  const PixelNoise interpolated = pixelNoise(interpolatedTwice(depth, kWidth, kHeight));
  std::printf("correlation / repeated: independent %.3f / %.2f, repeated %.3f / %.2f, interpolated %.3f / %.2f\n",
              independent.correlation, independent.repeated, repeated.correlation, repeated.repeated, interpolated.correlation,
              interpolated.repeated);
  EXPECT_LT(independent.correlation, -0.15f);  // a 6-term fit to 25 independent residuals: about -0.3
  EXPECT_GT(repeated.correlation, 0.0f);       // shared noise: over 0
  EXPECT_GT(interpolated.correlation, 0.0f);
  EXPECT_LT(independent.repeated, 0.1f);  // continuous depths: none repeated
  EXPECT_EQ(repeated.repeated, 1.0f);     // every depth copied over its 2 x 2 block
  EXPECT_LT(interpolated.repeated, 0.1f);
}

TEST(CorrelatedNoise, NoDepthImageCannotBeJudged) {
  PointCloud cloud = test::depthImage(kWidth, kHeight, kFx, [](int, int) { return 800.0f; });
  EXPECT_TRUE(std::isnan(pixelNoise(cloud).correlation));  // no noise at all
  cloud.fx = 0;  // no pinhole: not a depth image
  EXPECT_TRUE(std::isnan(pixelNoise(cloud).repeated));
  PointCloud shuffled = test::depthImage(kWidth, kHeight, kFx, [](int u, int) { return 800.0f + static_cast<float>(u % 3); });
  std::swap(shuffled.pixel[10], shuffled.pixel[11]);  // out of pixel order
  EXPECT_TRUE(std::isnan(pixelNoise(shuffled).correlation));
}

TEST(CorrelatedNoise, RepeatedPixelsAreThinnedBackToTheOriginalImage) {
  const std::vector<float> depth = noisyDepths(kWidth, kHeight, 11);
  const PointCloud original = test::depthImage(kWidth, kHeight, kFx, [&](int u, int v) { return at(depth, kWidth, u, v); });
  const PointCloud dense = repeatedTwice(depth, kWidth, kHeight);
  StageSettings p;
  int stride = 0;
  const std::optional<PointCloud> thinned = thinnedToIndependentNoise(dense, p, stride);
  ASSERT_TRUE(thinned.has_value());
  EXPECT_EQ(stride, 2);
  ASSERT_EQ(thinned->size(), original.size());
  EXPECT_EQ(thinned->width, kWidth);
  EXPECT_EQ(thinned->height, kHeight);
  for (std::size_t i = 0; i < original.size(); ++i) {
    ASSERT_EQ(thinned->pixel[i], original.pixel[i]);
    EXPECT_FLOAT_EQ(thinned->points[i].z(), original.points[i].z());
    // Each point projects onto its own pixel through the halved intrinsics.
    const Vec3& q = thinned->points[i];
    EXPECT_NEAR(thinned->fx * q.x() / q.z() + thinned->cx, static_cast<float>(thinned->pixel[i] % kWidth), 1e-3f);
    EXPECT_NEAR(thinned->fy * q.y() / q.z() + thinned->cy, static_cast<float>(thinned->pixel[i] / kWidth), 1e-3f);
  }
  EXPECT_FALSE(thinnedToIndependentNoise(original, p, stride).has_value());  // its noise is its own
  EXPECT_EQ(stride, 1);
  // Interpolated pixels share their noise too, but hold mixes of samples, not copies: halved, they
  // would keep the mix and lose half of the scan.
  EXPECT_FALSE(thinnedToIndependentNoise(interpolatedTwice(depth, kWidth, kHeight), p, stride).has_value());
  p.thin_correlated_pixels = false;
  EXPECT_FALSE(thinnedToIndependentNoise(dense, p, stride).has_value());
}
