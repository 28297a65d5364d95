// Noise shared by neighbouring pixels, found from the residuals of small quadric fits.
#include "correlated_noise.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace binpose {
namespace {

/// Windows sampled: enough for a steady quartile, few enough to cost well under a millisecond.
constexpr std::size_t kWindows = 512;
/// A window's half side in pixels (5 x 5 pixels, the noise estimate's 24 neighbours and itself).
constexpr int kHalf = 2;
constexpr int kSide = 2 * kHalf + 1;
constexpr int kWindowPixels = kSide * kSide;
/// Full windows the quartile needs; fewer and the scan is not judged.
constexpr std::size_t kLeastWindows = 32;
/// A window whose residuals' RMS is under this (mm) is noiseless: floating point rounding alone.
constexpr double kLeastResidual = 1e-4;
/// Over this correlation the noise is shared by neighbouring pixels ... Measured on the simulated
/// sensors' bins (ideal, industrial, structured light, time of flight; the 170 fresh and unseen
/// bins of docs/benchmarks.md, 500 to 1500 mm, and a 3 MP industrial view): -0.33 to -0.17; on
/// the real Kinect frames of IC-BIN -0.16 to -0.10; on structured-light bins and the IC-BIN frames
/// upsampled 2x to 4x by repeating each pixel 0.03-0.09 (at 2x their 25 pixels hold 9 samples,
/// and the fit's 6 terms take most of what they share), bilinear 0.15-0.17. The margin is wide on
/// the side of the scans matched well today: a scan it misses is matched as before.
constexpr float kCorrelated = 0.0f;
/// ... and from this share of repeated depths on, by copies of one depth (a registration to a
/// camera with 2 or more times the pixels each way repeats every depth along both: 1.000 on all
/// of the bins and frames above, 0.64-0.72 at 1.5 times). Native scans read 0-0.44 (simulated:
/// the structured-light model's disparity steps the most) and 0.62-0.87 (IC-BIN's depths in whole
/// millimetres, in steps of 3 mm there); smoothed or interpolated ones 0-0.08. Their pixels carry
/// a mix of samples, not copies: halved, they keep the mix and lose half of the scan (the bins
/// smoothed by 0.7 pixel: 89 found unthinned, 67 halved).
constexpr float kRepeatedShare = 0.95f;
/// The image is halved at most this many times (to a quarter of its columns and rows) ...
constexpr int kMostHalvings = 2;
/// ... and never below this many columns and rows (QQVGA).
constexpr int kLeastColumns = 160;
constexpr int kLeastRows = 120;

/// Whether the cloud is a depth image the windows can be read from: a pinhole camera's, one point
/// per pixel, in pixel order.
bool depthImage(const PointCloud& scan) {
  if (!scan.organized() || !(scan.fx > 0) || !(scan.fy > 0) || scan.pixel.size() != scan.size()) return false;
  const std::int64_t pixels = std::int64_t(scan.width) * scan.height;
  for (std::size_t i = 0; i < scan.size(); ++i)
    if (scan.pixel[i] < 0 || scan.pixel[i] >= pixels || (i > 0 && scan.pixel[i] <= scan.pixel[i - 1])) return false;
  return true;
}

/// The point seen through pixel `px`, or -1 (the points are in pixel order).
std::int64_t pointAt(const PointCloud& scan, std::int32_t px) {
  const auto it = std::lower_bound(scan.pixel.begin(), scan.pixel.end(), px);
  return it != scan.pixel.end() && *it == px ? it - scan.pixel.begin() : -1;
}

/// The matrix that takes a window's depths (row-major) to their residuals from the quadric in
/// the pixels' offsets fitted to them by least squares, I - A (A^T A)^-1 A^T. In the image the
/// window's design is the same everywhere; a plane's depth over a few pixels is a quadric in them
/// to well under a micrometre. (In 3-D, a plane fitted to a window whose noise is wider than the
/// window, a time-of-flight scan's, takes the wrong axis for the normal.)
using Window = Eigen::Matrix<double, kWindowPixels, 1>;
const Eigen::Matrix<double, kWindowPixels, kWindowPixels>& residualMaker() {
  static const auto maker = [] {
    Eigen::Matrix<double, kWindowPixels, 6> A;
    for (int k = 0; k < kWindowPixels; ++k) {
      const double x = k % kSide - kHalf, y = k / kSide - kHalf;
      A.row(k) << 1, x, y, x * x, x * y, y * y;
    }
    const Eigen::Matrix<double, 6, 6> normal = A.transpose() * A;
    return Eigen::Matrix<double, kWindowPixels, kWindowPixels>(Eigen::Matrix<double, kWindowPixels, kWindowPixels>::Identity() -
                                                               A * normal.ldlt().solve(A.transpose()));
  }();
  return maker;
}

/// The mean product of the residuals of pixels side by side or one above the other, over their
/// mean square.
float neighbourCorrelation(const Window& r) {
  double products = 0, squares = 0;
  int pairs = 0;
  for (int v = 0; v < kSide; ++v)
    for (int u = 0; u < kSide; ++u) {
      const double here = r(v * kSide + u);
      squares += here * here;
      if (u + 1 < kSide) products += here * r(v * kSide + u + 1), ++pairs;
      if (v + 1 < kSide) products += here * r((v + 1) * kSide + u), ++pairs;
    }
  return static_cast<float>((products / pairs) / (squares / kWindowPixels));
}

/// Whether the window's centre depth is repeated exactly by a pixel beside it and by one above or
/// below it.
bool repeatedAlongBoth(const Window& depth) {
  constexpr int c = kHalf * kSide + kHalf;
  const double z = depth(c);
  return (depth(c - 1) == z || depth(c + 1) == z) && (depth(c - kSide) == z || depth(c + kSide) == z);
}

/// The depths of the full window around point i's pixel (row-major), mm; false when a pixel of
/// it has none.
bool windowAround(const PointCloud& scan, std::size_t i, Window& window) {
  const int u = scan.pixel[i] % scan.width, v = scan.pixel[i] / scan.width;
  if (u < kHalf || v < kHalf || u + kHalf >= scan.width || v + kHalf >= scan.height) return false;
  for (int dv = -kHalf; dv <= kHalf; ++dv)
    for (int du = -kHalf; du <= kHalf; ++du) {
      const std::int64_t j = pointAt(scan, (v + dv) * scan.width + u + du);
      if (j < 0 || !scan.points[std::size_t(j)].allFinite()) return false;
      window((dv + kHalf) * kSide + du + kHalf) = scan.points[std::size_t(j)].z();
    }
  return true;
}

}  // namespace

PixelNoise pixelNoise(const PointCloud& scan) {
  PixelNoise out;
  if (!depthImage(scan)) return out;
  const std::size_t step = std::max<std::size_t>(1, scan.size() / kWindows);
  std::vector<float> correlations;
  std::size_t repeated = 0;
  Window depths;
  for (std::size_t i = step / 2; i < scan.size(); i += step) {
    if (!windowAround(scan, i, depths)) continue;
    const Window residual = residualMaker() * depths;
    if (residual.norm() < kLeastResidual * std::sqrt(double(kWindowPixels))) continue;
    correlations.push_back(neighbourCorrelation(residual));
    repeated += repeatedAlongBoth(depths);
  }
  if (correlations.size() < kLeastWindows) return out;
  const auto quartile = correlations.begin() + static_cast<long>(correlations.size() / 4);
  std::nth_element(correlations.begin(), quartile, correlations.end());
  out.correlation = *quartile;
  out.repeated = static_cast<float>(repeated) / static_cast<float>(correlations.size());
  return out;
}

PointCloud halvedImage(const PointCloud& scan) {
  PointCloud out;
  out.width = (scan.width + 1) / 2;
  out.height = (scan.height + 1) / 2;
  out.viewpoint = scan.viewpoint;
  out.has_viewpoint = scan.has_viewpoint;
  // Pixel u = fx X / Z + cx of the full image is pixel u / 2 = (fx / 2) X / Z + cx / 2 of this one.
  out.fx = scan.fx / 2, out.fy = scan.fy / 2, out.cx = scan.cx / 2, out.cy = scan.cy / 2;
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const int u = scan.pixel[i] % scan.width, v = scan.pixel[i] / scan.width;
    if (u % 2 != 0 || v % 2 != 0) continue;
    out.points.push_back(scan.points[i]);
    if (scan.hasNormals()) out.normals.push_back(scan.normals[i]);
    out.pixel.push_back((v / 2) * out.width + u / 2);
  }
  return out;
}

std::optional<PointCloud> thinnedToIndependentNoise(const PointCloud& scan, const StageSettings& p, int& stride) {
  stride = 1;
  std::optional<PointCloud> out;
  if (!p.adapt_to_noise || !p.thin_correlated_pixels) return out;
  for (int halvings = 0; halvings < kMostHalvings; ++halvings) {
    const PointCloud& now = out ? *out : scan;
    if ((now.width + 1) / 2 < kLeastColumns || (now.height + 1) / 2 < kLeastRows) break;
    const PixelNoise noise = pixelNoise(now);
    if (!(noise.correlation > kCorrelated && noise.repeated >= kRepeatedShare)) break;
    out = halvedImage(now);
    stride *= 2;
  }
  return out;
}

}  // namespace binpose
