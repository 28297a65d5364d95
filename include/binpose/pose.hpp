#pragma once
#include <vector>
// Rigid pose from correspondences (thesis 4.6, eq. 17-28: Horn et al. 1988).
#include <binpose/types.hpp>

#include <Eigen/Geometry>

namespace binpose {

using Pose = Eigen::Isometry3f;  ///< p_scene = R p_model + t, mm

/// The turn by `angle` (radians) about the line through `point` along the unit `axis`.
inline Pose turnAbout(const Vec3& axis, float angle, const Vec3& point) {
  Pose t = Pose::Identity();
  t.linear() = Eigen::AngleAxisf(angle, axis).toRotationMatrix();
  t.translation() = point - t.linear() * point;
  return t;
}

/// Whether `r` is a proper rotation (orthonormal within 1e-3, determinant +1): a pose read from a
/// user's file or array must be one before it is used as rigid.
inline bool isRotation(const Eigen::Matrix3f& r) {
  return (r.transpose() * r - Eigen::Matrix3f::Identity()).norm() <= 1e-3f && r.determinant() > 0;
}

struct PoseFit {
  Pose pose = Pose::Identity();
  float rms = 0;    ///< root-mean-square residual of the fit, mm
  bool ok = false;  ///< false: fewer than 3 pairs, a degenerate (collinear) set, or a mirror image
};

/// Least-squares rotation and translation taking `model` points onto `scene` points (same
/// order). Always a proper rotation; a set whose best orthogonal fit is a reflection (a
/// mirrored copy) is refused (ok = false) rather than forced into a wrong rotation.
PoseFit solvePose(const Points& model, const Points& scene);
/// solvePose with the caller's scratch `buffer` (reused from one call to the next); the same fit.
PoseFit solvePose(const Points& model, const Points& scene, std::vector<double>& buffer);

}  // namespace binpose
