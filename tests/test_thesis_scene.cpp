// Thesis-style synthetic scenes (7.4) and the thesis preset on them, against exact ground truth.
#include <binpose/detector.hpp>
#include <binpose/evaluation.hpp>
#include <binpose/geometry.hpp>
#include <binpose/kdtree.hpp>
#include <binpose/model.hpp>
#include <binpose/sampling.hpp>
#include <binpose/shapes.hpp>
#include <binpose/thesis_scene.hpp>

#include "test_util.hpp"

#include <algorithm>

using namespace binpose;

namespace {

EvalModel capModel(const Mesh& cap) {
  Symmetries s;
  s.continuous.push_back({Vec3::UnitZ(), Vec3::Zero()});
  return makeEvalModel(cap, s);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

// Every kept point lies on its copy's posed surface, the copies stay apart, and the occluder
// leaves each copy between min_kept and max_kept of its visible side.
TEST(ThesisScene, PointsOnThePosedCopiesWithVaryingOcclusion) {
  const Mesh cap = makeCap();
  ThesisSceneParams p;
  p.instances = 9;
  p.seed = 5;
  const SimulatedScene scene = simulateThesisScene(cap, p);
  ASSERT_EQ(scene.instances.size(), 9u);
  EXPECT_TRUE(scene.depth.empty());
  std::size_t on_surface = 0;
  float lo = 1, hi = 0;
  for (const SimulatedInstance& inst : scene.instances) {
    EXPECT_GT(inst.visible_fraction, 0.02f);
    EXPECT_LT(inst.visible_fraction, 0.6f) << "one side of a closed part at most";
    EXPECT_GE(inst.visib_fract, p.min_kept - 0.01f);
    EXPECT_LE(inst.visib_fract, p.max_kept + 0.01f);
    lo = std::min(lo, inst.visib_fract), hi = std::max(hi, inst.visib_fract);
  }
  EXPECT_GT(hi - lo, 0.3f) << "the occlusion varies";
  Points dense;  // the mesh's surface, 0.2 mm apart
  for (const SurfacePoint& sp : sampleSurfaceUniform(cap, 200000, 99)) dense.push_back(sp.point);
  const KdTree surface(dense);
  for (const Vec3& q : scene.cloud.points) {
    float best = INFINITY;
    for (const SimulatedInstance& inst : scene.instances) {
      std::uint32_t index;
      float d2;
      if (surface.nearest(inst.pose.inverse() * q, index, d2)) best = std::min(best, d2);
    }
    on_surface += std::sqrt(best) < 0.5f;
  }
  EXPECT_EQ(on_surface, scene.cloud.size());
  const SimulatedScene again = simulateThesisScene(cap, p);
  EXPECT_EQ(again.cloud.points, scene.cloud.points) << "the seed repeats";
}

// The thesis preset (chapter 5 as written, Table 7's parameters) on a thesis-style scene: most
// copies more than half visible are found, at the thesis's accuracy or better.
TEST(ThesisScene, ThesisPresetMeetsTheThesisAccuracy) {
  const Mesh cap = makeCap();
  ThesisSceneParams p;
  p.seed = 200;  // 16 caps
  const SimulatedScene scene = simulateThesisScene(cap, p);
  const OrientedModel model = prepareModel(cap, ModelParams{});
  const ModelDatabase db = ModelDatabase::build(model, defaultQuantization(model.diameter));
  const Detector detector(db, scaledToModel(thesisPreset(), model.diameter));
  const DetectionResult result = detector.detect(scene.cloud);
  std::vector<Pose> poses;
  for (const Detection& d : result.detections) poses.push_back(d.pose);
  GroundTruth truth;
  truth.instances = scene.instances;
  const EvaluationReport r = evaluate(truth, poses, result.timing.total_ms, capModel(cap));
  EXPECT_GE(r.recall_over_half_visible, 0.6);
  EXPECT_GE(r.precision, 0.7);
  std::vector<double> centroid, angle;
  for (const InstanceResult& i : r.instances)
    if (i.detection >= 0) centroid.push_back(i.errors.centroid_mm), angle.push_back(i.errors.angle_deg);
  EXPECT_LT(median(centroid), 2.0) << "the thesis: 0.55-0.85 mm over 10 scenes (docs/thesis_reproduction.md)";
  EXPECT_LT(median(angle), 7.5) << "the thesis: 3.5-7.5 degrees";
}
