#pragma once
// Internal: one step of point-to-plane ICP (refine.cpp, polish.cpp): a pair's share of the
// linearised 6-dof least squares, its solve, and the rigid motion it gives.
#include <binpose/pose.hpp>

#include <Eigen/Eigenvalues>

#include <cmath>

namespace binpose::detail {

/// ICP stops once a step moves no model point more than this, mm.
constexpr double kConverged = 1e-3;

/// Adds pair (model point p with normal n, scan point q) to the normal equations A x = b of a step
/// about centre c: the residual n.(q - p) against the step (omega, t), n.(omega x (p - c) + t).
inline void addPointToPlane(const Vec3& p, const Vec3& n, const Vec3& q, const Vec3& c, Eigen::Matrix<double, 6, 6>& A,
                            Eigen::Matrix<double, 6, 1>& b) {
  Eigen::Matrix<double, 6, 1> J;
  J << (p - c).cross(n).cast<double>(), n.cast<double>();
  const double r = n.dot(q - p);
  A += J * J.transpose();
  b += J * r;
}

/// Directions of the 6-dof step whose curvature is below this share of the largest one are
/// left alone (degeneracy-aware ICP, Zhang et al. 2016): the spin of a body of revolution, the
/// slide of a flat face. Solving for them fits noise, and the pose drifts there from step to step.
constexpr double kWeakDirection = 1e-3;

/// The least-squares step (omega, t) of A x = b, solved only along the constrained directions.
/// Rotations are scaled by `length` (mm at the part's reach) so both halves compare in mm.
inline Eigen::Matrix<double, 6, 1> constrainedStep(const Eigen::Matrix<double, 6, 6>& A, const Eigen::Matrix<double, 6, 1>& b,
                                                   double length) {
  Eigen::Matrix<double, 6, 1> scale;
  scale << Eigen::Vector3d::Constant(1.0 / length), Eigen::Vector3d::Ones();
  const Eigen::Matrix<double, 6, 6> As = scale.asDiagonal() * A * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(As);
  if (eig.info() != Eigen::Success) return Eigen::Matrix<double, 6, 1>::Constant(NAN);
  const auto& values = eig.eigenvalues();  // increasing
  const Eigen::Matrix<double, 6, 1> bs = scale.asDiagonal() * b;
  Eigen::Matrix<double, 6, 1> y = Eigen::Matrix<double, 6, 1>::Zero();
  for (int i = 0; i < 6; ++i)
    if (values(i) > kWeakDirection * values(5)) y += eig.eigenvectors().col(i) * (eig.eigenvectors().col(i).dot(bs) / values(i));
  return scale.asDiagonal() * y;
}

/// The most a step x = (omega, t) moves a model point, mm: its rotation at the part's reach
/// `length` plus its translation.
inline double stepMotion(const Eigen::Matrix<double, 6, 1>& x, double length) {
  return x.head<3>().norm() * length + x.tail<3>().norm();
}

/// The rigid step p -> R (p - c) + c + t of the solution x = (omega, t).
inline Pose stepAbout(const Vec3& c, const Eigen::Matrix<double, 6, 1>& x) {
  const Eigen::Vector3d omega = x.head<3>();
  Eigen::Matrix3f R = Eigen::Matrix3f::Identity();
  if (omega.norm() > 0) R = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix().cast<float>();
  Pose step = Pose::Identity();
  step.linear() = R;
  step.translation() = c - R * c + x.tail<3>().cast<float>();
  return step;
}

}  // namespace binpose::detail
