// ICP refinement and verification score.
#include <binpose/refine.hpp>

#include <Eigen/Cholesky>

#include <cmath>

namespace binpose {
namespace {

bool facesSensor(const Vec3& p, const Vec3& n, const Vec3& viewpoint) { return n.dot(viewpoint - p) > 0.0f; }

}  // namespace

Pose refinePose(const Pose& pose, const Points& model_points, const Points& model_normals, const Points& scan,
                const KdTree& scan_tree, const IcpParams& params) {
  Pose current = pose;
  float gate = params.max_distance;
  for (int it = 0; it < params.iterations; ++it) {
    Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    int pairs = 0;
    for (std::size_t i = 0; i < model_points.size(); ++i) {
      const Vec3 p = current * model_points[i];
      const Vec3 n = current.linear() * model_normals[i];
      if (!facesSensor(p, n, params.viewpoint)) continue;
      std::uint32_t j;
      float d2;
      if (!scan_tree.nearest(p, j, d2) || d2 > gate * gate) continue;
      // residual n.(q - p) against the increment (omega, t): n.(omega x p + t) = (p x n).omega + n.t
      Eigen::Matrix<double, 6, 1> J;
      J << p.cross(n).cast<double>(), n.cast<double>();
      const double r = n.dot(scan[j] - p);
      A += J * J.transpose();
      b += J * r;
      ++pairs;
    }
    if (pairs < 12) break;
    const Eigen::Matrix<double, 6, 1> x = A.ldlt().solve(b);
    if (!x.allFinite()) break;
    Pose step = Pose::Identity();
    const Eigen::Vector3d omega = x.head<3>();
    if (omega.norm() > 0) step.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix().cast<float>();
    step.translation() = x.tail<3>().cast<float>();
    current = step * current;
    gate = std::max(params.min_distance, gate * 0.7f);
    if (omega.norm() < 1e-5 && x.tail<3>().norm() < 1e-4) break;
  }
  return current;
}

float supportScore(const Pose& pose, const Points& model_points, const Points& model_normals, const KdTree& scan_tree,
                   float tolerance, const Vec3& viewpoint) {
  int facing = 0, supported = 0;
  for (std::size_t i = 0; i < model_points.size(); ++i) {
    const Vec3 p = pose * model_points[i];
    if (!facesSensor(p, pose.linear() * model_normals[i], viewpoint)) continue;
    ++facing;
    std::uint32_t j;
    float d2;
    if (scan_tree.nearest(p, j, d2) && d2 <= tolerance * tolerance) ++supported;
  }
  return facing == 0 ? 0.0f : static_cast<float>(supported) / static_cast<float>(facing);
}

}  // namespace binpose
