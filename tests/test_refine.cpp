// ICP refinement against synthetic views with exact ground truth.
#include <binpose/model.hpp>
#include <binpose/refine.hpp>
#include <binpose/shapes.hpp>

#include "synthetic.hpp"
#include "test_util.hpp"

namespace binpose {
namespace {

struct Case {
  Mesh mesh;
  OrientedModel model;
  Pose truth;
  PointCloud scan;
};

Case view(const Mesh& mesh, const Vec3& tilt_axis) {
  Case c{mesh, prepareModel(mesh, ModelParams{}), Pose::Identity(), {}};
  c.truth.linear() = Eigen::AngleAxisf(0.6f, tilt_axis.normalized()).toRotationMatrix();
  c.truth.translation() = Vec3(5, -8, 480);
  c.scan = test::renderCopies(mesh, {c.truth}, test::SyntheticView{}, [](std::size_t, const Vec3&) { return true; });
  return c;
}

Pose refine(const Case& c, const Pose& start) {
  const PointGrid grid(c.scan.points);
  return refinePose(start, c.model.points, c.model.normals, c.scan.points, grid, IcpParams{});
}

/// `pose` moved by `t` (mm) and turned by `angle` (rad) about `axis` through the part's origin.
Pose perturbed(const Pose& pose, const Vec3& t, float angle, const Vec3& axis) {
  Pose p = pose;
  p.linear() = pose.linear() * Eigen::AngleAxisf(angle, axis.normalized()).toRotationMatrix();
  p.translation() += t;
  return p;
}

double angleDeg(const Eigen::Matrix3f& a, const Eigen::Matrix3f& b) {
  return test::deg(Eigen::AngleAxisf(a.transpose() * b).angle());
}

TEST(Refine, ConvergesToTheTruthFromAMillimetreAndTwoDegreesOff) {
  const Case c = view(builtinPart("box"), Vec3(1, 2, 0.5f));
  const Pose start = perturbed(c.truth, Vec3(0.7f, -0.5f, 0.6f), 0.035f, Vec3(1, 1, 0));
  const Pose r = refine(c, start);
  EXPECT_LT((r.translation() - c.truth.translation()).norm(), 0.05);
  EXPECT_LT(angleDeg(r.linear(), c.truth.linear()), 0.1);
}

// A body of revolution fixes its axis but not its spin about it: ICP must find the axis and
// leave the spin where the start put it, not drift along the free direction on noise.
TEST(Refine, BodyOfRevolutionFindsItsAxisAndKeepsItsSpin) {
  const Case c = view(makeCap(), Vec3(1, -1, 0));
  const float spin = 0.5f;  // rad about the cap's axis (+z in the model)
  const Pose spun = perturbed(c.truth, Vec3::Zero(), spin, Vec3::UnitZ());
  const Pose start = perturbed(spun, Vec3(0.6f, 0.5f, -0.5f), 0.035f, Vec3(1, 0, 0));
  const Pose r = refine(c, start);
  const Vec3 axis = r.linear() * Vec3::UnitZ(), true_axis = c.truth.linear() * Vec3::UnitZ();
  EXPECT_LT(test::deg(std::acos(std::min(1.0f, axis.dot(true_axis)))), 0.1);
  // The part's origin lies on its axis: its position is fixed whatever the spin.
  EXPECT_LT((r.translation() - c.truth.translation()).norm(), 0.05);
  // Spin left: the angle between the refined and the spun start's orientations.
  EXPECT_LT(angleDeg(r.linear(), spun.linear()), 0.5);
}

// A part posed flush with the bin's floor is supported by every floor point under it; with the
// floor given as background it is not supported at all.
TEST(Evidence, TheBinsPlanesDoNotSupportAPart) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});  // 60 x 40 x 20, centred
  PointCloud floor;  // the plane z = 500 mm, seen from the origin
  for (float x = -100; x <= 100; x += 0.5f)
    for (float y = -100; y <= 100; y += 0.5f) floor.points.emplace_back(x, y, 500.0f);
  const PointGrid grid(floor.points);
  Pose flush = Pose::Identity();  // the box's -z face (facing the sensor) in the floor
  flush.translation() = Vec3(10, -5, 510);
  const auto score = [&](std::vector<Plane> background) {
    SceneEvidence evidence(floor.points, grid, Vec3::Zero());
    evidence.setBackground(std::move(background), 1.0f);
    return evidence.evaluate(flush, box.points, box.normals, 1.0f, box.sample_radius).score();
  };
  EXPECT_GT(score({}), 0.8f);
  EXPECT_LT(score({Plane{Vec3::UnitZ(), 500.0f}}), 0.05f);
  // A plane elsewhere changes nothing.
  EXPECT_GT(score({Plane{Vec3::UnitX(), 300.0f}}), 0.8f);
}

}  // namespace
}  // namespace binpose
