// Parts with a mirror plane (part_symmetry.hpp): the plane found on a made-up mirror-symmetric
// part and on IPD obj 0, none on a part without one, and a clique whose pairs fit only a mirror
// image of the part posed where the copy is.
#include <binpose/io.hpp>
#include <binpose/kdtree.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/pose.hpp>

#include "part_symmetry.hpp"
#include "test_util.hpp"

#include <random>

using namespace binpose;

namespace {

constexpr int kHalf = 60;  ///< points on one side of the mirror plane

/// A made-up part: kHalf random oriented points on one side of the plane x = 7 and their mirror
/// images (point i + kHalf is the image of point i). With `mirrored` false, the second half is
/// as random as the first: no mirror plane.
OrientedModel madeUpPart(std::uint64_t seed, bool mirrored) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  OrientedModel model;
  const auto point = [&] { return Vec3(7.0f + 1.0f + 25.0f * (u(rng) + 1.0f), 30.0f * u(rng), 12.0f * u(rng)); };
  for (int i = 0; i < kHalf; ++i) {
    model.points.push_back(point());
    model.normals.push_back(Vec3(u(rng), u(rng), u(rng)).normalized());
  }
  for (int i = 0; i < kHalf; ++i) {
    if (mirrored) {
      const Vec3& p = model.points[static_cast<std::size_t>(i)];
      const Vec3& n = model.normals[static_cast<std::size_t>(i)];
      model.points.push_back(Vec3(14.0f - p.x(), p.y(), p.z()));
      model.normals.push_back(Vec3(-n.x(), n.y(), n.z()));
    } else {
      const Vec3 p = point();
      model.points.push_back(Vec3(14.0f - p.x(), 0.7f * p.z(), 2.0f * p.y()));  // other spread, no image
      model.normals.push_back(Vec3(u(rng), u(rng), u(rng)).normalized());
    }
  }
  model.diameter = 90;
  model.sample_radius = 1;
  return model;
}

Pose somePose() {
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisf(0.9f, Vec3(-1, 2, 1).normalized()).toRotationMatrix();
  pose.translation() = Vec3(-35, 20, 610);
  return pose;
}

}  // namespace

TEST(MirrorSymmetry, PlaneOfAMadeUpPartAndNoneWithoutOne) {
  const auto plane = mirrorPlane(madeUpPart(5, true));
  ASSERT_TRUE(plane.has_value());
  EXPECT_GT(std::abs(plane->normal.x()), 0.999f) << plane->normal.transpose();
  EXPECT_NEAR(plane->d * plane->normal.x(), 7.0f, 1e-3f);  // the plane x = 7
  EXPECT_FALSE(mirrorPlane(madeUpPart(5, false)).has_value());
}

TEST(MirrorSymmetry, IpdObj0HasAMirrorPlane) {
  REQUIRE_DATA("ipd_parts/models/obj_000000.ply");
  const OrientedModel part = prepareModel(readMesh(test::dataPath("ipd_parts/models/obj_000000.ply")), ModelParams{});
  const auto plane = mirrorPlane(part);
  ASSERT_TRUE(plane.has_value());
  // Every model point's image lies on the part: within a sample spacing of a model point.
  KdTree tree(part.points);
  int off = 0;
  for (const Vec3& p : part.points) {
    std::uint32_t j;
    float d2;
    tree.nearest(plane->reflect(p), j, d2);
    off += d2 > 4 * part.sample_radius * part.sample_radius;
  }
  EXPECT_LT(off, static_cast<int>(part.points.size()) / 100) << off << " of " << part.points.size();
}

TEST(MirrorSymmetry, CliqueOfMirrorImagesFitsTheCopy) {
  const StageSettings settings;
  const Pose truth = somePose();
  for (const bool mirrored : {true, false}) {
    const OrientedModel part = madeUpPart(9, mirrored);
    const ModelDatabase db = ModelDatabase::build(part, QuantizationParams{});
    const PartSymmetry symmetry(db, settings);
    ASSERT_EQ(symmetry.kind(), PartSymmetry::Kind::None);
    // Each scene point is the posed mirror image (in the plane x = 7) of model point i, paired
    // with point i: the pairs fit only a mirror image of the part. On the mirror-symmetric part
    // that image is model point i + kHalf, where the copy shows it.
    Points scene, scene_normals;
    std::vector<Correspondence> clique;
    for (std::uint32_t i = 0; i < 12; ++i) {
      const Vec3& p = part.points[i];
      const Vec3& n = part.normals[i];
      scene.push_back(truth * Vec3(14.0f - p.x(), p.y(), p.z()));
      scene_normals.push_back(truth.linear() * Vec3(-n.x(), n.y(), n.z()));
      clique.push_back({i, i});
    }
    EXPECT_FALSE(solvePose(Points(part.points.begin(), part.points.begin() + 12), scene).ok);
    CliqueBuffers buffers;
    EXPECT_TRUE(symmetry.solve(clique, scene, scene_normals, part.points, buffers).empty());  // a mirror image: refused
    const std::vector<PoseFit> fits = symmetry.solve(clique, scene, scene_normals, part.points, buffers, true);
    if (!mirrored) {
      EXPECT_TRUE(fits.empty());  // no mirror plane to reflect them in
      continue;
    }
    ASSERT_EQ(fits.size(), 1u);
    EXPECT_LT(fits[0].rms, 1e-3f);
    EXPECT_LT((fits[0].pose.matrix() - truth.matrix()).cwiseAbs().maxCoeff(), 1e-3f);
  }
}
