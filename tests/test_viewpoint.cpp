// A scan whose file gives no sensor origin (viewpoint.hpp): the origin kept in the sensor's own
// frame, the sensor found above the bin in a world frame, and detection there.
#include <binpose/detector.hpp>
#include <binpose/evaluation.hpp>
#include <binpose/io.hpp>
#include <binpose/model_database.hpp>
#include <binpose/sensor_model.hpp>
#include <binpose/simulation.hpp>
#include <binpose/viewpoint.hpp>

#include "synthetic.hpp"
#include "test_util.hpp"

using namespace binpose;

namespace {

/// The world frame of these tests: the bin's (z up, floor at z = 0), turned by 0.6 rad about z
/// and moved, as a robot's base frame beside the bin would be.
Pose worldFromBin() {
  Pose w = Pose::Identity();
  w.linear() = Eigen::AngleAxisf(0.6f, Vec3::UnitZ()).toRotationMatrix();
  w.translation() = Vec3(400, -250, 750);
  return w;
}

/// IPD obj 8 in 12 copies seen by the structured-light model from 800 mm
/// (RealSensors.StructuredLightBinWithoutFalseDetections' bin).
struct Bin {
  Mesh mesh;
  OrientedModel model;
  SimulatedScene scene;
};

Bin structuredLightBin() {
  Bin b;
  b.mesh = readMesh(test::dataPath("ipd_parts/models/obj_000008.ply"));
  b.model = prepareModel(b.mesh, ModelParams{});
  SensorParams sensor;
  sensor.distance = 800.0f;
  sensor.model = sensorModel(SensorKind::StructuredLight);
  b.scene = renderBin(b.mesh, test::gridOfCopies(b.model, 12, 31), BinParams{}, sensor, 31);
  return b;
}

/// The scan's points moved by `frame_from_camera`, as an unorganized file holds them.
PointCloud unorganized(const SimulatedScene& scene, const Pose& frame_from_camera) {
  PointCloud cloud;
  for (const Vec3& p : scene.cloud.points) cloud.points.push_back(frame_from_camera * p);
  return cloud;
}

struct Found {
  int right = 0, wrong = 0;
};

/// Detections within 0.1 diameter (ADD-S) of a copy (`frame_from_camera` takes the copies'
/// poses into the detections' frame), and those of none.
Found tally(const std::vector<Detection>& detections, const SimulatedScene& scene, const EvalModel& eval,
            const Pose& frame_from_camera) {
  Found f;
  for (const Detection& d : detections) {
    const bool right = std::any_of(scene.instances.begin(), scene.instances.end(), [&](const SimulatedInstance& t) {
      return test::addSTo(d.pose, frame_from_camera * t.pose, eval) < 0.1f * eval.diameter;
    });
    ++(right ? f.right : f.wrong);
  }
  return f;
}

}  // namespace

// In the camera's own frame the origin sees the scan (nothing hidden but a few mixed pixels): kept.
TEST(Viewpoint, KeepsTheOriginOfTheSensorsFrame) {
  REQUIRE_DATA("ipd_parts/models/obj_000008.ply");
  const Bin b = structuredLightBin();
  const ViewpointGuess g = guessViewpoint(b.scene.cloud.points);
  EXPECT_FALSE(g.moved);
  EXPECT_LT(g.assumed_hidden, 0.05f);
  EXPECT_EQ(g.viewpoint, Vec3::Zero());
}

// In the world frame the origin lies under the bin's floor; the guess lies above the bin,
// within 15 degrees of the sensor's direction, and hides next to nothing.
TEST(Viewpoint, FindsTheSensorAboveABinInAWorldFrame) {
  REQUIRE_DATA("ipd_parts/models/obj_000008.ply");
  const Bin b = structuredLightBin();
  const Pose world_from_camera = worldFromBin() * b.scene.camera_from_world.inverse();
  const PointCloud world = unorganized(b.scene, world_from_camera);
  const ViewpointGuess g = guessViewpoint(world.points);
  ASSERT_TRUE(g.moved);
  EXPECT_GT(g.assumed_hidden, 0.2f);
  EXPECT_LT(g.hidden, 0.06f);
  Vec3 centre = Vec3::Zero();
  for (const Vec3& p : world.points) centre += p;
  centre /= static_cast<float>(world.points.size());
  const Vec3 sensor = world_from_camera.translation();
  const float cosine = (g.viewpoint - centre).normalized().dot((sensor - centre).normalized());
  EXPECT_GT(cosine, std::cos(15.0f * float(M_PI) / 180.0f));
}

// The noisy bin as an unorganized file in the world frame: from the guessed viewpoint, at least
// half of the copies more than half visible and nothing wrong (the depth image's own standard,
// RealSensors.StructuredLightBinWithoutFalseDetections); from the origin, normals face the wrong
// way and the scan's noise is misread: far fewer.
TEST(Viewpoint, DetectsInAWorldFrameFromTheGuess) {
  REQUIRE_DATA("ipd_parts/models/obj_000008.ply");
  const Bin b = structuredLightBin();
  const ModelDatabase db = ModelDatabase::build(b.model, defaultQuantization(b.model.diameter));
  const EvalModel eval = makeEvalModel(b.mesh, readSymmetries(test::dataPath("ipd_parts/models/models_info.json"), "8"));
  const Pose world_from_camera = worldFromBin() * b.scene.camera_from_world.inverse();
  const PointCloud world = unorganized(b.scene, world_from_camera);
  DetectionParams params = scaledToModel(defaultPreset(), b.model.diameter);
  const Found from_origin = tally(Detector(db, params).detect(world).detections, b.scene, eval, world_from_camera);
  params.viewpoint = guessViewpoint(world.points).viewpoint;
  const DetectionResult result = Detector(db, params).detect(world);
  EXPECT_GT(result.noise_mm, 0.4f);  // the sensor's noise is seen in the unorganized cloud too
  const Found guessed = tally(result.detections, b.scene, eval, world_from_camera);
  int half_visible = 0;
  for (const SimulatedInstance& t : b.scene.instances) half_visible += t.visib_fract > 0.5f;
  EXPECT_EQ(guessed.wrong, 0);
  EXPECT_GE(2 * guessed.right, half_visible) << guessed.right << " of " << half_visible;
  EXPECT_GT(guessed.right, from_origin.right + 2) << "from the origin: " << from_origin.right;
}

// What no sensor gives keeps the assumed origin: nothing, one point, one point many times over,
// points too far apart for a float's extent.
TEST(Viewpoint, DegenerateScansKeepTheOrigin) {
  const Vec3 assumed(1, 2, 3);
  for (const Points& scan : {Points{}, Points{Vec3(0, 0, 500)}, Points(1000, Vec3(5, 5, 5)),
                             Points{Vec3(-3e38f, 0, 0), Vec3(3e38f, 0, 0), Vec3(0, 3e38f, 1), Vec3(0, 0, -3e38f)}}) {
    const ViewpointGuess g = guessViewpoint(scan, assumed);
    EXPECT_FALSE(g.moved);
    EXPECT_EQ(g.viewpoint, assumed);
    EXPECT_TRUE(std::isfinite(g.hidden));
  }
}
