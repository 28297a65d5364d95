// Closed-form rigid pose (thesis 4.6).
#include <binpose/pose.hpp>

#include <Eigen/SVD>
#include <Eigen/Geometry>

#include <vector>

namespace binpose {

PoseFit solvePose(const Points& model, const Points& scene) {
  std::vector<double> buffer;
  return solvePose(model, scene, buffer);
}

PoseFit solvePose(const Points& model, const Points& scene, std::vector<double>& buffer) {
  PoseFit fit;
  const auto n = static_cast<Eigen::Index>(model.size());
  if (n < 3 || model.size() != scene.size()) return fit;
  // The four 3 x n matrices over the caller's buffer (a clique fit of a part of n-fold symmetry
  // solves eight poses of 3 to 20 points, each of which allocated four matrices; an Eigen
  // matrix reallocates whenever its size changes, a vector only when it grows).
  buffer.resize(static_cast<std::size_t>(12 * n));
  using Columns = Eigen::Map<Eigen::Matrix3Xd>;
  Columns M(buffer.data(), 3, n), S(buffer.data() + 3 * n, 3, n), Mc(buffer.data() + 6 * n, 3, n), Sc(buffer.data() + 9 * n, 3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    M.col(i) = model[static_cast<std::size_t>(i)].cast<double>();
    S.col(i) = scene[static_cast<std::size_t>(i)].cast<double>();
  }
  // Cross-covariance of the centred sets (eq. 19-26); its SVD gives R = U diag(1, 1, d) V^T.
  const Eigen::Vector3d cm = M.rowwise().mean(), cs = S.rowwise().mean();
  Sc = S.colwise() - cs;  // the product's operands as it evaluated them itself
  Mc = M.colwise() - cm;
  const Eigen::Matrix3d D = Sc * Mc.transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(D, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv[1] > 1e-9 * sv[0])) return fit;  // collinear: rotation about the line is undetermined
  const double d = (svd.matrixU() * svd.matrixV().transpose()).determinant();
  if (d < 0 && sv[2] > 1e-3 * sv[0]) return fit;  // a genuine mirror image, not planar noise
  Eigen::Matrix3d R = svd.matrixU() * Eigen::Vector3d(1, 1, d < 0 ? -1 : 1).asDiagonal() * svd.matrixV().transpose();
  fit.pose.linear() = R.cast<float>();
  fit.pose.translation() = (cs - R * cm).cast<float>();
  double sum = 0;
  for (Eigen::Index i = 0; i < n; ++i) sum += (R * (M.col(i) - cm) + cs - S.col(i)).squaredNorm();
  fit.rms = static_cast<float>(std::sqrt(sum / static_cast<double>(n)));
  fit.ok = true;
  return fit;
}

}  // namespace binpose
