// The simulator's ground truth and the evaluation's metrics against hand-made cases.
#include <binpose/evaluation.hpp>
#include <binpose/geometry.hpp>
#include <binpose/kdtree.hpp>
#include <binpose/model.hpp>
#include <binpose/sampling.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>

#include "test_util.hpp"

using namespace binpose;

namespace {
Pose worldPose(const Vec3& t, float angle_deg = 0, const Vec3& axis = Vec3::UnitX()) {
  Pose p = Pose::Identity();
  p.linear() = Eigen::AngleAxisf(angle_deg * float(M_PI) / 180.0f, axis.normalized()).toRotationMatrix();
  p.translation() = t;
  return p;
}

EvalModel capModel() {
  Symmetries s;
  s.continuous.push_back({Vec3::UnitZ(), Vec3::Zero()});
  return makeEvalModel(makeCap(), s);
}
}  // namespace

TEST(Simulation, RenderedPointsLieOnThePosedMesh) {
  SensorParams sensor;
  sensor.noise_sigma = 0;  // exact depth, up to the 0.1 mm depth unit
  const Mesh cap = makeCap();
  const Pose world = worldPose(Vec3(10, -5, 40), 35, Vec3(1, 1, 0));
  const SimulatedScene scene = renderBin(cap, {world}, BinParams{}, sensor, 1);
  ASSERT_EQ(scene.instances.size(), 1u);
  // Dense samples of the posed surface with their normals: every scan point near the part lies on it.
  const Points normals = faceNormals(cap);
  Points surface, surface_n;
  for (const auto& s : sampleSurfaceUniform(cap, 200000, 3)) {
    surface.push_back(scene.instances[0].pose * s.point);
    surface_n.push_back(scene.instances[0].pose.linear() * normals[s.face]);
  }
  const KdTree tree(surface);
  int on_part = 0;
  for (const Vec3& p : scene.cloud.points) {
    std::uint32_t idx[8];
    float d2[8];
    const std::size_t n = tree.knn(p, 8, idx, d2);
    if (d2[0] > 2.0f * 2.0f) continue;  // the bin
    ++on_part;
    // distance to the surface: the least over the nearest samples' tangent planes (one of them
    // lies on the right face, also next to a crease)
    float distance = INFINITY;
    for (std::size_t k = 0; k < n; ++k) distance = std::min(distance, std::abs(surface_n[idx[k]].dot(p - surface[idx[k]])));
    // depth quantised to 0.1 mm: at most 0.05 mm along the ray, less along the normal
    ASSERT_LT(distance, 0.06f) << p.transpose();
  }
  EXPECT_GT(on_part, 2000);
  EXPECT_EQ(on_part, scene.instances[0].visible_pixels);
}

TEST(Simulation, VisibleFractionOfALoneSphereIsAboutAHalf) {
  const float R = 30;
  const SensorParams sensor;
  const SimulatedScene scene = renderBin(makeSphere(R, 5), {worldPose(Vec3(0, 0, R))}, BinParams{}, sensor, 2);
  // From a point at distance D from the centre, a sphere shows a cap of (1 - R/D)/2 of its area.
  const float D = sensor.distance - R;
  EXPECT_NEAR(scene.instances[0].visible_fraction, (1 - R / D) / 2, 0.02);
  EXPECT_NEAR(scene.instances[0].visib_fract, 1.0f, 0.01f);  // nothing in front of it
}

TEST(Simulation, PartsRestInsideTheBinAndTheSeedRepeats) {
  const BinParams bin;
  const auto a = dropIntoBin(makeCap(), 12, bin, 3.0f, 7);
  const auto b = dropIntoBin(makeCap(), 12, bin, 3.0f, 7);
  ASSERT_EQ(a.size(), 12u);
  const Vec3 c = surfaceCentroid(makeCap());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Vec3 p = a[i] * c;
    EXPECT_LT(std::abs(p.x()), bin.inner.x() / 2) << i;
    EXPECT_LT(std::abs(p.y()), bin.inner.y() / 2) << i;
    EXPECT_GT(p.z(), 0.0f) << i;
    EXPECT_LT(p.z(), 3 * 62.0f) << i << ": resting low in the bin, not still falling";
    EXPECT_TRUE(a[i].matrix() == b[i].matrix()) << "same seed, same drop";
  }
}

TEST(Metrics, SpinAboutTheSymmetryAxisIsNoError) {
  const EvalModel m = capModel();
  const Pose truth = worldPose(Vec3(5, 6, 480), 40, Vec3(1, 2, 3));
  const Pose spun = truth * worldPose(Vec3::Zero(), 73, Vec3::UnitZ());  // the cap turned about its own axis
  const PoseErrors e = poseErrors(spun, truth, m);
  EXPECT_LT(e.centroid_mm, 1e-3f);
  EXPECT_LT(e.angle_deg, 0.05f);
  EXPECT_LT(e.add_s_mm, 0.02f);
  EXPECT_LT(e.mssd_mm, 0.3f);  // continuous symmetry sampled every degree: r * 0.5 deg
}

TEST(Metrics, KnownOffsetAndTilt) {
  const EvalModel m = capModel();
  const Pose truth = worldPose(Vec3(0, 0, 480), 20, Vec3(0, 1, 0));
  Pose shifted = truth;
  shifted.translation() += Vec3(1.5f, -2.0f, 0.0f);  // 2.5 mm
  PoseErrors e = poseErrors(shifted, truth, m);
  EXPECT_NEAR(e.centroid_mm, 2.5f, 1e-3f);
  EXPECT_NEAR(e.mssd_mm, 2.5f, 0.01f);
  EXPECT_LE(e.add_s_mm, 2.5f);
  EXPECT_LT(e.angle_deg, 1e-3f);
  const Pose tilted = truth * worldPose(Vec3::Zero(), 10, Vec3::UnitX());  // tilt the axis by 10 degrees
  e = poseErrors(tilted, truth, m);
  EXPECT_NEAR(e.angle_deg, 10.0f, 0.01f);
  // An asymmetric part has no free spin: the same 73 degree turn is a 73 degree error.
  const EvalModel box = makeEvalModel(makeBox({60, 40, 20}), Symmetries{});
  EXPECT_NEAR(poseErrors(truth * worldPose(Vec3::Zero(), 73, Vec3::UnitZ()), truth, box).angle_deg, 73.0f, 0.01f);
}

TEST(Metrics, DiscreteSymmetriesOfABox) {
  Symmetries s;  // a 60 x 40 x 20 box: half turns about its three axes
  for (int a = 0; a < 3; ++a) {
    Vec3 axis = Vec3::Zero();
    axis[a] = 1;
    s.discrete.push_back(worldPose(Vec3::Zero(), 180, axis));
  }
  const EvalModel box = makeEvalModel(makeBox({60, 40, 20}), s);
  const Pose truth = worldPose(Vec3(0, 0, 500), 30, Vec3(1, 1, 1));
  const PoseErrors e = poseErrors(truth * worldPose(Vec3::Zero(), 180, Vec3::UnitY()), truth, box);
  EXPECT_LT(e.angle_deg, 0.01f);
  EXPECT_LT(e.mssd_mm, 1e-3f);
}

TEST(Matching, OneToOneAndThreshold) {
  const EvalModel m = capModel();
  GroundTruth truth;
  SimulatedInstance a, b;
  a.pose = worldPose(Vec3(-50, 0, 480));
  b.pose = worldPose(Vec3(50, 0, 480));
  a.visib_fract = 0.9f;
  b.visib_fract = 0.3f;
  truth.instances = {a, b};
  Pose near_a = a.pose;
  near_a.translation() += Vec3(0.5f, 0, 0);
  Pose far = a.pose;
  far.translation() += Vec3(0, 30, 0);  // beyond 0.1 x diameter
  // Two detections of copy a: only one may match; the better one does.
  const EvaluationReport r = evaluate(truth, {near_a, a.pose, far}, 30.0, m);
  EXPECT_EQ(r.matched, 1);
  EXPECT_EQ(r.instances[0].detection, 1);
  EXPECT_EQ(r.instances[1].detection, -1);
  EXPECT_DOUBLE_EQ(r.recall, 0.5);
  EXPECT_DOUBLE_EQ(r.precision, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(r.recall_over_half_visible, 1.0);
  EXPECT_DOUBLE_EQ(r.ms_per_object, 30.0);
}

// ---- sensor models ------------------------------------------------------------------------------

namespace {

/// The depths (mm) of the pixels of `scene` inside the rectangle [u0, u1) x [v0, v1); 0: none.
std::vector<float> depthsIn(const SimulatedScene& scene, int u0, int u1, int v0, int v1) {
  std::vector<float> out;
  for (int v = v0; v < v1; ++v)
    for (int u = u0; u < u1; ++u)
      out.push_back(static_cast<float>(scene.depth[static_cast<std::size_t>(v) * scene.intrinsics.width + u] *
                                       scene.intrinsics.depth_scale));
  return out;
}

/// Mean and standard deviation of the non-zero values.
std::pair<double, double> meanAndSigma(const std::vector<float>& values) {
  double sum = 0, sum2 = 0;
  int n = 0;
  for (const float v : values)
    if (v > 0) sum += v, sum2 += double(v) * v, ++n;
  const double mean = sum / n;
  return {mean, std::sqrt(std::max(0.0, sum2 / n - mean * mean))};
}

SensorParams sensorAt(float distance, SensorKind kind) {
  SensorParams s;
  s.distance = distance;
  s.model = sensorModel(kind);
  return s;
}

}  // namespace

// The structured-light model on the empty bin's floor, 800 mm away, seen head-on: Nguyen et al.'s
// axial noise there is 1.2 + 1.9 (0.8 - 0.4)^2 = 1.50 mm, and the depth comes from a disparity
// quantised to 1/8 px, so the floor reads in steps of z^2 / (f b) / 8 = 1.94 mm (f = 550 px,
// b = 75 mm). The ideal sensor's 0.1 mm at 500 mm is 0.26 mm there.
TEST(SensorModel, StructuredLightFloorNoiseAndDisparitySteps) {
  const SimulatedScene sl = renderBin(builtinPart("cap"), {}, BinParams{}, sensorAt(800, SensorKind::StructuredLight), 3);
  const std::vector<float> floor = depthsIn(sl, 270, 370, 190, 290);  // the middle of the floor
  const auto [mean, sigma] = meanAndSigma(floor);
  EXPECT_NEAR(mean, 800.0, 0.5);
  const double expected = std::sqrt(1.50 * 1.50 + 1.94 * 1.94 / 12);  // noise, then the step's rounding
  EXPECT_NEAR(sigma, expected, 0.25 * expected);
  std::vector<float> levels;
  for (const float d : floor)
    if (d > 0) levels.push_back(d);
  std::sort(levels.begin(), levels.end());
  levels.erase(std::unique(levels.begin(), levels.end(), [](float a, float b) { return std::abs(a - b) < 0.3f; }), levels.end());
  ASSERT_GT(levels.size(), 2u);
  for (std::size_t i = 1; i < levels.size(); ++i) EXPECT_GT(levels[i] - levels[i - 1], 1.5f) << "no disparity step at " << levels[i];
  const SimulatedScene ideal = renderBin(builtinPart("cap"), {}, BinParams{}, sensorAt(800, SensorKind::Ideal), 3);
  EXPECT_NEAR(meanAndSigma(depthsIn(ideal, 270, 370, 190, 290)).second, 0.1 * 1.6 * 1.6, 0.05);
}

// A 60 x 40 x 100 mm box standing on the floor, 800 mm below the camera. The projector, 75 mm
// to the camera's +x, cannot see the floor from 4 to 15 mm beyond the box's -x edge (the camera
// sees it from 4 mm on), so a strip 6-13 mm out reads nothing there; on the +x side it is lit.
// Edge drop-outs strike both sides alike: the difference is the shadow's.
TEST(SensorModel, StructuredLightProjectorShadowsOneSideOfAPart) {
  const Pose standing = worldPose(Vec3(0, 0, 50));
  const Mesh box = makeBox({60.0f, 40.0f, 100.0f});
  const auto uAt = [](float x) { return static_cast<int>(std::lround(319.5 + 550.0 * x / 800.0)); };  // on the floor
  const auto missing = [&](const SimulatedScene& scene, float x0, float x1) {
    const std::vector<float> d = depthsIn(scene, uAt(x0), uAt(x1), 230, 250);
    return static_cast<double>(std::count(d.begin(), d.end(), 0.0f)) / static_cast<double>(d.size());
  };
  const SimulatedScene sl = renderBin(box, {standing}, BinParams{}, sensorAt(800, SensorKind::StructuredLight), 5);
  EXPECT_GT(missing(sl, -43, -36), 0.9) << "the floor beyond the box's -x edge should be in the projector's shadow";
  EXPECT_LT(missing(sl, 36, 43), 0.2);
  const SimulatedScene ideal = renderBin(box, {standing}, BinParams{}, sensorAt(800, SensorKind::Ideal), 5);
  EXPECT_EQ(missing(ideal, -43, -36), 0.0) << "the ideal sensor has no projector";
}

TEST(SensorModel, NamesParseAndUnknownIsRefused) {
  for (const SensorKind k : {SensorKind::Ideal, SensorKind::StructuredLight, SensorKind::Industrial, SensorKind::TimeOfFlight})
    EXPECT_EQ(parseSensorKind(sensorKindName(k)), k);
  EXPECT_THROW(parseSensorKind("kinect"), Error);
}
