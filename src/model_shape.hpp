#pragma once
// The model's extent as the online stages ask about it: is a point near the model (removal,
// 5.2.6), do two poses put it in the same place (symmetry-aware), does one posed copy mostly
// overlap another (duplicate suppression).
#include <binpose/cyclic_symmetry.hpp>
#include <binpose/point_grid.hpp>
#include <binpose/pose.hpp>
#include <binpose/symmetry.hpp>

#include <optional>
#include <vector>

namespace binpose {

class ModelShape {
 public:
  /// `points`: the model's; `cell`: the near-model grid's cell, mm; `overlap_points`: an even
  /// share of the model points, for mostlyOverlaps; `axis`: a body of revolution's (its turn is
  /// free); `cyclic`: an n-fold symmetry's (its turns are the same pose).
  ModelShape(const Points& points, float diameter, float cell, Points overlap_points, const RevolutionAxis* axis,
             const CyclicSymmetry* cyclic);

  /// True when x (in the model's frame) lies within `distance` of a model point. A point that
  /// far outside the model's bounding box is answered without a grid query.
  [[nodiscard]] bool near(const Vec3& x, float distance) const;
  /// True when poses `a` and `b` put the model in nearly the same place: the centroids within
  /// `share` x 0.1 diameter of each other, and the turn between them moving no model point by
  /// more than that; for a body of revolution, the turn of its axis only. A near-symmetric flip
  /// of a part is another pose, not the same.
  [[nodiscard]] bool samePose(const Pose& a, const Pose& b, float share = 1.0f) const;
  /// True when over half of the overlap points, posed by `a`, lie within 0.1 diameter of the
  /// model posed by `b`.
  [[nodiscard]] bool mostlyOverlaps(const Pose& a, const Pose& b) const;

  [[nodiscard]] const Vec3& centroid() const { return centroid_; }
  /// Largest distance of a model point from the centroid, mm.
  [[nodiscard]] float radius() const { return radius_; }

 private:
  PointGrid grid_;
  Points overlap_points_;
  float diameter_ = 0;
  Vec3 centroid_ = Vec3::Zero();
  float radius_ = 0;
  Vec3 lo_, hi_;
  std::optional<Vec3> revolution_axis_;
  std::vector<Eigen::Matrix3f> turns_;  ///< the cyclic symmetry's turns k = 1 .. n-1
};

}  // namespace binpose
