// A model's flat faces (face_hypotheses.hpp), against the faces of a box of known size.
#include <binpose/model.hpp>
#include <binpose/shapes.hpp>

#include "face_hypotheses.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

namespace binpose {
namespace {

// The built-in box, 60 x 40 x 20 mm about its centre: six faces, each with its outward normal,
// its centre at half a side from the box's and its area within a sample's share of the truth;
// a sphere, curved everywhere, has none.
TEST(FlatFaces, ABoxHasItsSixFacesAndASphereNone) {
  const OrientedModel box = prepareModel(builtinPart("box"), ModelParams{});
  const float per_point = static_cast<float>(box.area / static_cast<double>(box.points.size()));
  const std::vector<ModelFace> faces = flatFaces(box.points, box.normals, box.sample_radius, per_point, 300.0f);
  ASSERT_EQ(faces.size(), 6u);
  const Vec3 half(30, 20, 10);
  for (int axis = 0; axis < 3; ++axis)
    for (const float sign : {-1.0f, 1.0f}) {
      const Vec3 normal = sign * Vec3::Unit(axis);
      const auto face = std::find_if(faces.begin(), faces.end(), [&](const ModelFace& f) { return f.normal.dot(normal) > 0.999f; });
      ASSERT_NE(face, faces.end()) << "no face along " << normal.transpose();
      EXPECT_NEAR(face->centre[axis], sign * half[axis], 0.2f);
      const float area = 4.0f * half[(axis + 1) % 3] * half[(axis + 2) % 3];
      EXPECT_NEAR(face->area, area, 0.1f * area) << "face along " << normal.transpose();
      EXPECT_TRUE(face->turns);
    }
  const OrientedModel sphere = prepareModel(makeSphere(30.0f), ModelParams{});
  const float sphere_per_point = static_cast<float>(sphere.area / static_cast<double>(sphere.points.size()));
  EXPECT_TRUE(flatFaces(sphere.points, sphere.normals, sphere.sample_radius, sphere_per_point, 300.0f).empty());
}

}  // namespace
}  // namespace binpose
