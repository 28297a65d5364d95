// Oriented point-pair features (thesis 4.2).
#include <binpose/features.hpp>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace binpose {

float angleBetween(const Vec3& a, const Vec3& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

namespace {

/// acos by Abramowitz & Stegun 4.4.46 (|error| <= 2e-8 rad in exact arithmetic, about 1e-6 rad
/// in float): a polynomial and one square root instead of std::acos (the cap's database build
/// 903 -> 836 ms), and the same function builds the database and reads the scene.
float fastAcos(float c) {
  const float x = std::min(std::abs(c), 1.0f);
  float p = -0.0012624911f;
  p = p * x + 0.0066700901f;
  p = p * x - 0.0170881256f;
  p = p * x + 0.0308918810f;
  p = p * x - 0.0501743046f;
  p = p * x + 0.0889789874f;
  p = p * x - 0.2145988016f;
  p = p * x + 1.5707963050f;
  const float a = std::sqrt(1.0f - x) * p;
  return c < 0 ? std::numbers::pi_v<float> - a : a;
}

}  // namespace

bool computeFeature(const Vec3& m1, const Vec3& n1, const Vec3& m2, const Vec3& n2, PairFeature& f) {
  const Vec3 d = m2 - m1;  // eq. 3
  f.d = d.norm();
  if (!(f.d > 0.0f)) return false;
  // eq. 2 by acos of unit dot products: within 0.02 degrees of the exact angle even near 0 and
  // 180 degrees (float rounding), far below d_angle.
  const Vec3 u = d / f.d;
  f.theta1 = fastAcos(n1.dot(u));
  f.theta2 = fastAcos(n2.dot(u));
  f.theta3 = fastAcos(n1.dot(n2));
  return true;
}

KeySpace::KeySpace(const QuantizationParams& params, float max_distance) : params_(params) {
  if (!(params.d_dist > 0) || !std::isfinite(params.d_dist))
    throw Error(fmt::format("d_dist must be a positive length in mm, got {}", params.d_dist));
  if (!(params.d_angle > 0) || params.d_angle > std::numbers::pi_v<float>)
    throw Error(fmt::format("d_angle must lie in (0, 180] degrees, got {}", params.d_angle * 180 / std::numbers::pi));
  if (!(params.overlap >= 0) || params.overlap >= 0.5f)
    throw Error(fmt::format("overlap p_d must lie in [0, 0.5), got {}", params.overlap));
  if (!(max_distance > 0) || !std::isfinite(max_distance))
    throw Error(fmt::format("key space needs a positive model diameter, got {}", max_distance));
  const double n_dist = std::floor(max_distance / params.d_dist) + 2.0;  // +1 for the top overlap bin
  n_angle_ = static_cast<int>(std::floor(std::numbers::pi / params.d_angle)) + 1;
  const double total = n_dist * n_angle_ * n_angle_ * n_angle_;
  if (total > double(1u << 28))
    throw Error(fmt::format("d_dist {} mm is too fine for a {} mm model ({:.0f} keys); use a larger d_dist",
                            params.d_dist, max_distance, total));
  n_dist_ = static_cast<int>(n_dist);
  size_ = static_cast<std::uint32_t>(total);
}

void KeySpace::bins(float value, float step, int n_bins, int& first, int& second) const {
  const float scaled = value / step;
  first = std::min(static_cast<int>(std::floor(scaled)), n_bins - 1);  // eq. 4 (pi falls in the last bin)
  second = -1;
  const float frac = scaled - static_cast<float>(first);
  if (frac < params_.overlap && first > 0) second = first - 1;  // eq. 7, lower neighbour
  else if (frac > 1.0f - params_.overlap && first + 1 < n_bins) second = first + 1;  // upper neighbour
}

std::uint32_t KeySpace::key(const PairFeature& f) const {
  const auto mu_d = static_cast<int>(std::floor(f.d / params_.d_dist));
  if (mu_d < 0 || mu_d >= n_dist_) return kInvalid;
  auto angle_bin = [&](float a) { return std::min(static_cast<int>(a / params_.d_angle), n_angle_ - 1); };
  const auto nA = static_cast<std::uint32_t>(n_angle_);
  return ((static_cast<std::uint32_t>(mu_d) * nA + angle_bin(f.theta1)) * nA + angle_bin(f.theta2)) * nA +
         angle_bin(f.theta3);
}

int KeySpace::overlapKeys(const PairFeature& f, std::array<std::uint32_t, kMaxKeys>& out) const {
  int b[4][2];
  bins(f.d, params_.d_dist, n_dist_, b[0][0], b[0][1]);
  if (b[0][0] < 0 || f.d >= params_.d_dist * static_cast<float>(n_dist_)) return 0;
  bins(f.theta1, params_.d_angle, n_angle_, b[1][0], b[1][1]);
  bins(f.theta2, params_.d_angle, n_angle_, b[2][0], b[2][1]);
  bins(f.theta3, params_.d_angle, n_angle_, b[3][0], b[3][1]);
  const auto nA = static_cast<std::uint32_t>(n_angle_);
  int count = 0;
  for (int i0 = 0; i0 < 2; ++i0) {
    if (b[0][i0] < 0) continue;
    for (int i1 = 0; i1 < 2; ++i1) {
      if (b[1][i1] < 0) continue;
      for (int i2 = 0; i2 < 2; ++i2) {
        if (b[2][i2] < 0) continue;
        for (int i3 = 0; i3 < 2; ++i3) {
          if (b[3][i3] < 0) continue;
          out[count++] = ((static_cast<std::uint32_t>(b[0][i0]) * nA + b[1][i1]) * nA + b[2][i2]) * nA + b[3][i3];
        }
      }
    }
  }
  return count;
}

}  // namespace binpose
