// A part's near-symmetric half turns (near_flips.hpp), against parts whose turns are known.
#include <binpose/io.hpp>
#include <binpose/model.hpp>
#include <binpose/shapes.hpp>

#include "face_hypotheses.hpp"
#include "model_shape.hpp"
#include "near_flips.hpp"
#include "test_util.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace binpose {
namespace {

ModelShape shapeOf(const OrientedModel& model) {
  return ModelShape(model.points, model.diameter, 0.05f * model.diameter, model.points, nullptr, nullptr);
}

std::vector<Pose> flipsOf(const OrientedModel& model) { return nearFlips(model.points, model.normals, shapeOf(model)); }

/// True when `turn` is a half turn (within 3 degrees) about a line along `axis` (within
/// `degrees`) through `point` (within `within` mm).
bool halfTurnAbout(const Pose& turn, const Vec3& axis, const Vec3& point, float degrees, float within = 1.0f) {
  const Eigen::AngleAxisf aa(turn.linear());
  const float angle_off = std::abs(aa.angle() - static_cast<float>(M_PI)) * 180.0f / static_cast<float>(M_PI);
  const float axis_off = std::acos(std::min(1.0f, std::abs(aa.axis().dot(axis.normalized())))) * 180.0f / static_cast<float>(M_PI);
  return angle_off < 3.0f && axis_off < degrees && (turn * point - point).norm() < within;
}

// The built-in box, 60 x 40 x 20 mm about its centre, is its own image under a half turn about
// each of its three axes: those three, and no other.
TEST(NearFlips, ABoxTurnsOntoItselfAboutItsThreeAxes) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});
  const std::vector<Pose> flips = flipsOf(box);
  ASSERT_EQ(flips.size(), 3u);
  for (int axis = 0; axis < 3; ++axis)
    EXPECT_TRUE(std::any_of(flips.begin(), flips.end(), [&](const Pose& f) { return halfTurnAbout(f, Vec3::Unit(axis), Vec3::Zero(), 3.0f); }))
        << "no half turn about axis " << axis;
}

// IPD obj 1 is nearly its own image under a half turn about the diagonal (x - z)/sqrt(2) of its
// frame: the turn that the noisy bins' detections of it are found turned over by.
TEST(NearFlips, IpdPartOneTurnsOntoItselfAboutItsDiagonal) {
  REQUIRE_DATA("ipd_parts/models/obj_000001.ply");
  const OrientedModel part = prepareModel(readMesh(test::dataPath("ipd_parts/models/obj_000001.ply")), ModelParams{});
  const std::vector<Pose> flips = flipsOf(part);
  ASSERT_FALSE(flips.empty());
  const Eigen::AngleAxisf best(flips.front().linear());
  const float off = std::acos(std::min(1.0f, std::abs(best.axis().dot(Vec3(1, 0, -1).normalized())))) * 180.0f / static_cast<float>(M_PI);
  EXPECT_LT(off, 10.0f);
  EXPECT_NEAR(best.angle(), static_cast<float>(M_PI), 0.1f);
}

// IPD obj 1 is two 3 mm plates at right angles: plate A at x 35.1-38.1 mm, plate B at z -28.6 to
// -25.5 mm. Seen face-on by one plate, a copy is laid over its mirror image across that plate;
// the turns tried on a quiet scan hold the half turns about lines in each plate's mid-plane that
// undo it (along z through plate A, along x through plate B; plate B is nearly square, so its
// principal axes may lie a few degrees off x), which no near-symmetric turn is.
TEST(NearFlips, IpdPartOneTurnsOverEachOfItsPlates) {
  REQUIRE_DATA("ipd_parts/models/obj_000001.ply");
  const OrientedModel part = prepareModel(readMesh(test::dataPath("ipd_parts/models/obj_000001.ply")), ModelParams{});
  const ModelShape shape = shapeOf(part);
  const float per_point = static_cast<float>(part.area / static_cast<double>(part.points.size()));
  const std::vector<ModelFace> faces =
      flatFaces(part.points, part.normals, part.sample_radius, per_point, 0.0625f * part.diameter * part.diameter);
  const std::vector<Pose> near = flipsOf(part);
  const std::vector<Pose> turns = withFaceFlips(near, faces, shape);
  const auto has = [](const std::vector<Pose>& set, const Vec3& axis, const Vec3& point) {
    return std::any_of(set.begin(), set.end(), [&](const Pose& t) { return halfTurnAbout(t, axis, point, 5.0f, 1.5f); });
  };
  const Vec3 plate_a(36.6f, 0.0f, 0.0f), plate_b(0.0f, 0.0f, -27.05f);
  EXPECT_TRUE(has(turns, Vec3::UnitZ(), plate_a));
  EXPECT_TRUE(has(turns, Vec3::UnitX(), plate_b));
  EXPECT_FALSE(has(near, Vec3::UnitZ(), plate_a));
  EXPECT_LE(turns.size(), near.size() + 2 * faces.size());  // two turns a face at most
}

}  // namespace
}  // namespace binpose
