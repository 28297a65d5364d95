// The model's extent and pose comparisons for removal, duplicate checks and suppression.
#include "model_shape.hpp"

#include <binpose/geometry.hpp>

#include <algorithm>
#include <cmath>

namespace binpose {
namespace {

/// The usual correctness radius (ADD < 0.1 d): two poses closer than this are one placement.
constexpr float kSamePlaceShare = 0.1f;

}  // namespace

ModelShape::ModelShape(const Points& points, float diameter, float cell, Points overlap_points, const RevolutionAxis* axis,
                       const CyclicSymmetry* cyclic)
    : grid_(points, cell), overlap_points_(std::move(overlap_points)), diameter_(diameter) {
  for (const Vec3& p : points) centroid_ += p;
  centroid_ /= static_cast<float>(points.size());
  for (const Vec3& p : points) radius_ = std::max(radius_, (p - centroid_).norm());
  bounds(points, lo_, hi_);
  if (axis != nullptr) revolution_axis_ = axis->direction;
  if (cyclic != nullptr)
    for (int k = 1; k < cyclic->order; ++k) turns_.push_back(cyclic->turn(k).linear());
}

bool ModelShape::near(const Vec3& x, float distance) const {
  // Most points of a neighbouring part's pose, or of the scene around a found part, lie far
  // outside the model's box: no grid query for them.
  if ((x.array() < lo_.array() - distance).any() || (x.array() > hi_.array() + distance).any()) return false;
  return grid_.anyWithin(x, distance);
}

bool ModelShape::samePose(const Pose& a, const Pose& b, float share) const {
  const float tolerance = share * kSamePlaceShare * diameter_;
  if ((a * centroid_ - b * centroid_).squaredNorm() > tolerance * tolerance) return false;
  if (revolution_axis_) {  // the turn about the axis is free: the axis's end moves radius_ times its change
    const Vec3& axis = *revolution_axis_;
    return radius_ * (a.linear() * axis - b.linear() * axis).norm() <= tolerance;
  }
  // A turn by angle t moves a point at distance r from its axis by 2 r sin(t / 2); for a part of
  // n-fold symmetry, the least turn from a to one of b's n images.
  const Eigen::Matrix3f a_to_b = a.linear().transpose() * b.linear();
  float turn = Eigen::AngleAxisf(a_to_b).angle();
  for (const Eigen::Matrix3f& t : turns_) turn = std::min(turn, Eigen::AngleAxisf(a_to_b * t).angle());
  return 2.0f * radius_ * std::sin(0.5f * turn) <= tolerance;
}

bool ModelShape::mostlyOverlaps(const Pose& a, const Pose& b) const {
  if ((a * centroid_ - b * centroid_).norm() > 2 * radius_) return false;
  const Pose b_from_a = b.inverse() * a;
  const float near_distance = kSamePlaceShare * diameter_;
  const std::size_t half = overlap_points_.size() / 2;
  std::size_t hits = 0, misses = 0;
  for (const Vec3& m : overlap_points_) {  // stops as soon as the answer is known
    if (near(b_from_a * m, near_distance)) {
      if (++hits > half) return true;
    } else if (++misses >= overlap_points_.size() - half) {
      return false;
    }
  }
  return false;
}

}  // namespace binpose
