// Flying pixels (flying_pixels.hpp): points between two surfaces go, surfaces stay.
#include <binpose/sensor_model.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>

#include "flying_pixels.hpp"
#include "stage_settings.hpp"
#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

using namespace binpose;

namespace {

constexpr float kFx = 550.0f;

/// A depth image of `width` x `height` pixels through a pinhole of focal length kFx, depth(u, v)
/// in mm (0: no point), as an organized cloud in pixel order.
PointCloud image(int width, int height, const std::function<float(int, int)>& depth) {
  return test::depthImage(width, height, kFx, depth);
}

}  // namespace

// A step from a surface at 700 mm to one at 760 mm, 1.5 mm of noise on both: the pixels along
// the step that read a mix of the two (a quarter to three quarters of the way) go; the surfaces
// stay, their edge pixels too.
TEST(FlyingPixels, MixedPixelsAtAStepGoTheSurfacesStay) {
  constexpr float kSigma = 1.5f;
  Rng rng(7);
  std::vector<char> mixed(64 * 48, 0);
  const PointCloud cloud = image(64, 48, [&](int u, int v) {
    const float noise = kSigma * test::gaussian(rng);
    if (u == 32 && v % 2 == 0) {  // every other pixel of the step's column reads a mix
      mixed[static_cast<std::size_t>(v * 64 + u)] = 1;
      return 700.0f + 60.0f * (0.25f + 0.5f * static_cast<float>(rng.uniform())) + noise;
    }
    return (u < 32 ? 700.0f : 760.0f) + noise;
  });
  const std::vector<char> flying = flyingPixels(cloud, kSigma);
  ASSERT_EQ(flying.size(), cloud.size());
  int mixes = 0, mixes_found = 0, others_found = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const bool is_mix = mixed[static_cast<std::size_t>(cloud.pixel[i])] != 0;
    mixes += is_mix;
    mixes_found += is_mix && flying[i];
    others_found += !is_mix && flying[i];
  }
  ASSERT_EQ(mixes, 24);
  EXPECT_GE(mixes_found, 22) << "of " << mixes;
  EXPECT_EQ(others_found, 0);
}

// A surface at 55 degrees to the line of sight steps by 1.4 pixel footprints a pixel, as far as
// a mix at a step: it is kept, noise and all.
TEST(FlyingPixels, ASteepSurfaceStays) {
  constexpr float kSigma = 1.0f;
  Rng rng(8);
  const float step = std::tan(55.0f * 3.14159265f / 180.0f) * 800.0f / kFx;
  const PointCloud cloud =
      image(64, 48, [&](int u, int) { return 800.0f + step * static_cast<float>(u - 32) + kSigma * test::gaussian(rng); });
  const std::vector<char> flying = flyingPixels(cloud, kSigma);
  ASSERT_EQ(flying.size(), cloud.size());
  EXPECT_EQ(std::count(flying.begin(), flying.end(), 1), 0);
}

// Only a depth image's pixels have neighbours to be judged by: an unorganized cloud, or one
// without the pinhole's focal length, is left as it is.
TEST(FlyingPixels, OnlyADepthImageIsJudged) {
  PointCloud cloud = image(8, 8, [](int u, int) { return u == 4 ? 730.0f : u < 4 ? 700.0f : 760.0f; });
  EXPECT_FALSE(flyingPixels(cloud, 1.0f).empty());
  PointCloud unorganized = cloud;
  unorganized.width = unorganized.height = 0;
  EXPECT_TRUE(flyingPixels(unorganized, 1.0f).empty());
  cloud.fx = 0;
  EXPECT_TRUE(flyingPixels(cloud, 1.0f).empty());
  EXPECT_FALSE(withoutFlyingPixels(unorganized, StageSettings{}).has_value());
}

// The time-of-flight model's flying pixels, against the same bin rendered without noise: a point
// that reads more than 7 mm (3 of the model's sigmas there) from every surface its pixel and the
// pixels around it see is a flying pixel. Over a fifth of them go, and most of what goes is one.
// The thesis's preset keeps the scan as it is.
TEST(FlyingPixels, TimeOfFlightBinLosesItsFlyingPixels) {
  const Mesh mesh = makeCap();
  SimulationParams sp;
  sp.instances = 10;
  sp.seed = 21;
  sp.sensor.distance = 800.0f;
  const std::vector<Pose> poses = dropIntoBin(mesh, sp.instances, sp.bin, sp.settle_seconds, sp.seed);
  SensorParams ideal = sp.sensor, tof = sp.sensor;
  ideal.noise_sigma = 0.0f;
  tof.model = sensorModel(SensorKind::TimeOfFlight);
  tof.model.multipath_gain = 0;  // its bias would read as off the surfaces too
  const SimulatedScene truth = renderBin(mesh, poses, sp.bin, ideal, sp.seed);
  const SimulatedScene seen = renderBin(mesh, poses, sp.bin, tof, sp.seed);
  const int width = seen.intrinsics.width, height = seen.intrinsics.height;
  const auto trueDepth = [&](int u, int v) {
    return u < 0 || v < 0 || u >= width || v >= height
               ? 0.0f
               : static_cast<float>(truth.depth[static_cast<std::size_t>(v * width + u)] * ideal.depth_scale);
  };
  const auto offEverySurface = [&](const PointCloud& cloud, std::size_t i) {
    const int u = cloud.pixel[i] % width, v = cloud.pixel[i] / width;
    for (int dv = -1; dv <= 1; ++dv)
      for (int du = -1; du <= 1; ++du)
        if (const float z = trueDepth(u + du, v + dv); z > 0 && std::abs(z - cloud.points[i].z()) <= 7.0f) return false;
    return true;
  };
  const std::optional<PointCloud> kept = withoutFlyingPixels(seen.cloud, StageSettings{});
  ASSERT_TRUE(kept.has_value());
  int flying = 0, flying_kept = 0;
  for (std::size_t i = 0; i < seen.cloud.size(); ++i) flying += offEverySurface(seen.cloud, i);
  for (std::size_t i = 0; i < kept->size(); ++i) flying_kept += offEverySurface(*kept, i);
  const int dropped = static_cast<int>(seen.cloud.size() - kept->size());
  ASSERT_GT(flying, 200);
  // 109 of 423 and 109 of 158 today: a mix within the jump of one of its surfaces, or beside two
  // others of about its own depth, stays.
  EXPECT_GT(flying - flying_kept, flying / 5) << "of " << flying << " flying pixels";
  EXPECT_GT(flying - flying_kept, dropped / 2) << "of " << dropped << " dropped";
  StageSettings thesis = StageSettings{};
  thesis.adapt_to_noise = false;
  EXPECT_FALSE(withoutFlyingPixels(seen.cloud, thesis).has_value());
}
