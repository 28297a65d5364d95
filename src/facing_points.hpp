#pragma once
// The posed model's points that the sensor faces (SceneEvidence's score and outline).
#include <binpose/refine.hpp>

#include <vector>

namespace binpose {

/// A sensor-facing point of the posed model, with its range and direction in the image frame.
struct Facing {
  Vec3 p, n;  ///< posed point and normal
  float range, u, v;
  bool grazing;  ///< seen at more than the grazing angle (cos_grazing_angle)
};

/// The posed model's points that face the viewpoint and lie in front of it, in model order;
/// `to_view` turns a direction into the image frame (z along the line of sight).
std::vector<Facing> facingPoints(const Pose& pose, const PreparedModel& model, const Eigen::Matrix3f& to_view,
                                 const Vec3& viewpoint, float cos_grazing_angle);

}  // namespace binpose
