// Oriented point-pair features (thesis 4.2).
#include <binpose/features.hpp>

#include "simd.hpp"

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
  const double n_angle = std::floor(std::numbers::pi / params.d_angle) + 1.0;
  const double total = n_dist * n_angle * n_angle * n_angle;
  if (total > double(1u << 28))
    throw Error(fmt::format("d_dist {} mm and d_angle {} degrees are too fine for a {} mm model ({:.3g} keys); "
                            "use larger steps", params.d_dist, params.d_angle * 180 / std::numbers::pi, max_distance, total));
  n_dist_ = static_cast<int>(n_dist);
  n_angle_ = static_cast<int>(n_angle);
  size_ = static_cast<std::uint32_t>(total);
}

void KeySpace::bins(float value, float step, int n_bins, int& first, int& second) const {
  const float scaled = value / step;
  // eq. 4 (pi falls in the last bin); clamped before the cast, which a huge value would overflow
  first = static_cast<int>(std::fmin(std::floor(scaled), static_cast<float>(n_bins - 1)));
  second = -1;
  const float frac = scaled - static_cast<float>(first);
  if (frac < params_.overlap && first > 0) second = first - 1;  // eq. 7, lower neighbour
  else if (frac > 1.0f - params_.overlap && first + 1 < n_bins) second = first + 1;  // upper neighbour
}

std::uint32_t KeySpace::key(const PairFeature& f) const {
  const float scaled = std::floor(f.d / params_.d_dist);
  if (!(scaled >= 0.0f) || scaled >= static_cast<float>(n_dist_)) return kInvalid;
  const auto mu_d = static_cast<int>(scaled);
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

namespace {

void featureKeysScalar(const Vec3& p, const Vec3& n, const Points& points, const Points& normals,
                       std::span<const std::uint32_t> others, std::uint32_t skip, const KeySpace& keys,
                       std::vector<std::uint32_t>& out) {
  for (const std::uint32_t o : others) {
    PairFeature f;
    if (o != skip && computeFeature(p, n, points[o], normals[o], f)) out.push_back(keys.key(f));
  }
}

#if defined(__x86_64__)
/// fastAcos on 8 lanes, the same operations in the same order (no fused multiply-add).
BINPOSE_AVX2_INLINE __m256 fastAcos8(__m256 c) {
  const __m256 x = _mm256_min_ps(_mm256_andnot_ps(_mm256_set1_ps(-0.0f), c), _mm256_set1_ps(1.0f));
  __m256 q = _mm256_set1_ps(-0.0012624911f);
  q = _mm256_add_ps(_mm256_mul_ps(q, x), _mm256_set1_ps(0.0066700901f));
  q = _mm256_sub_ps(_mm256_mul_ps(q, x), _mm256_set1_ps(0.0170881256f));
  q = _mm256_add_ps(_mm256_mul_ps(q, x), _mm256_set1_ps(0.0308918810f));
  q = _mm256_sub_ps(_mm256_mul_ps(q, x), _mm256_set1_ps(0.0501743046f));
  q = _mm256_add_ps(_mm256_mul_ps(q, x), _mm256_set1_ps(0.0889789874f));
  q = _mm256_sub_ps(_mm256_mul_ps(q, x), _mm256_set1_ps(0.2145988016f));
  q = _mm256_add_ps(_mm256_mul_ps(q, x), _mm256_set1_ps(1.5707963050f));
  const __m256 a = _mm256_mul_ps(_mm256_sqrt_ps(_mm256_sub_ps(_mm256_set1_ps(1.0f), x)), q);
  const __m256 negative = _mm256_cmp_ps(c, _mm256_setzero_ps(), _CMP_LT_OQ);
  return _mm256_blendv_ps(a, _mm256_sub_ps(_mm256_set1_ps(std::numbers::pi_v<float>), a), negative);
}

/// a . b of 3-vectors in lanes, summed as Eigen sums a Vector3f's: a0 b0 + (a1 b1 + a2 b2).
BINPOSE_AVX2_INLINE __m256 dot8(__m256 ax, __m256 ay, __m256 az, __m256 bx, __m256 by, __m256 bz) {
  return _mm256_add_ps(_mm256_mul_ps(ax, bx), _mm256_add_ps(_mm256_mul_ps(ay, by), _mm256_mul_ps(az, bz)));
}

/// KeySpace::key's angle bin on 8 lanes: min(trunc(a / d_angle), nA - 1).
BINPOSE_AVX2_INLINE __m256i angleBin8(__m256 a, __m256 step, __m256i last) {
  return _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_div_ps(a, step)), last);
}

/// computeFeature on 8 lanes, its operations in its order: the features (d, theta1, theta2,
/// theta3) from one oriented point to the 8 points partner(0..7) with their normals.
struct Features8 {
  __m256 d, theta1, theta2, theta3;
};
struct Point8 {  ///< one oriented point, broadcast to 8 lanes
  __m256 px, py, pz, nx, ny, nz;
};
BINPOSE_AVX2_INLINE Point8 broadcast8(const Vec3& p, const Vec3& n) {
  return {_mm256_set1_ps(p.x()), _mm256_set1_ps(p.y()), _mm256_set1_ps(p.z()),
          _mm256_set1_ps(n.x()), _mm256_set1_ps(n.y()), _mm256_set1_ps(n.z())};
}
template <class Partner>
BINPOSE_AVX2_INLINE Features8 features8(const Point8& o, const Points& points, const Points& normals, Partner partner) {
  alignas(32) float q[6][8];
  for (int l = 0; l < 8; ++l) {  // the 8 partners' points and normals, a lane each
    const Vec3& m = points[partner(l)];
    const Vec3& mn = normals[partner(l)];
    q[0][l] = m.x(), q[1][l] = m.y(), q[2][l] = m.z(), q[3][l] = mn.x(), q[4][l] = mn.y(), q[5][l] = mn.z();
  }
  // eq. 3: d = m2 - m1, |d| as Eigen's norm (sqrt of x^2 + (y^2 + z^2)), u = d / |d|.
  const __m256 dx = _mm256_sub_ps(_mm256_load_ps(q[0]), o.px), dy = _mm256_sub_ps(_mm256_load_ps(q[1]), o.py),
               dz = _mm256_sub_ps(_mm256_load_ps(q[2]), o.pz);
  const __m256 d = _mm256_sqrt_ps(dot8(dx, dy, dz, dx, dy, dz));
  const __m256 ux = _mm256_div_ps(dx, d), uy = _mm256_div_ps(dy, d), uz = _mm256_div_ps(dz, d);
  const __m256 mx = _mm256_load_ps(q[3]), my = _mm256_load_ps(q[4]), mz = _mm256_load_ps(q[5]);
  // eq. 2
  return {d, fastAcos8(dot8(o.nx, o.ny, o.nz, ux, uy, uz)), fastAcos8(dot8(mx, my, mz, ux, uy, uz)),
          fastAcos8(dot8(o.nx, o.ny, o.nz, mx, my, mz))};
}

__attribute__((target("avx2"))) void featureKeysAvx2(const Vec3& p, const Vec3& n, const Points& points,
                                                     const Points& normals, std::span<const std::uint32_t> others,
                                                     std::uint32_t skip, const KeySpace& keys,
                                                     std::vector<std::uint32_t>& out) {
  const Point8 o = broadcast8(p, n);
  const __m256 d_dist = _mm256_set1_ps(keys.params().d_dist), d_angle = _mm256_set1_ps(keys.params().d_angle);
  const __m256 n_dist = _mm256_set1_ps(static_cast<float>(keys.distanceBins()));
  const auto nA = keys.angleBins();
  const __m256i last = _mm256_set1_epi32(nA - 1), vnA = _mm256_set1_epi32(nA);
  alignas(32) std::uint32_t key[8];
  std::size_t i = 0;
  for (; i + 8 <= others.size(); i += 8) {
    const Features8 f = features8(o, points, normals, [&](int l) { return others[i + l]; });
    const __m256 d = f.d;
    // eq. 4-5: the three angles' bins and the distance's.
    const __m256i b1 = angleBin8(f.theta1, d_angle, last);
    const __m256i b2 = angleBin8(f.theta2, d_angle, last);
    const __m256i b3 = angleBin8(f.theta3, d_angle, last);
    const __m256 mu_d = _mm256_floor_ps(_mm256_div_ps(d, d_dist));
    __m256i k = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(mu_d), vnA), b1);
    k = _mm256_add_epi32(_mm256_mullo_epi32(k, vnA), b2);
    k = _mm256_add_epi32(_mm256_mullo_epi32(k, vnA), b3);
    const __m256i beyond = _mm256_castps_si256(_mm256_cmp_ps(mu_d, n_dist, _CMP_GE_OQ));
    _mm256_store_si256(reinterpret_cast<__m256i*>(key), _mm256_or_si256(k, beyond));  // kInvalid is all ones
    const auto defined = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(d, _mm256_setzero_ps(), _CMP_GT_OQ)));
    for (int l = 0; l < 8; ++l)
      if (((defined >> l) & 1) != 0 && others[i + l] != skip) out.push_back(key[l]);
  }
  featureKeysScalar(p, n, points, normals, others.subspan(i), skip, keys, out);
}
#else
void featureKeysAvx2(const Vec3& p, const Vec3& n, const Points& points, const Points& normals,
                     std::span<const std::uint32_t> others, std::uint32_t skip, const KeySpace& keys,
                     std::vector<std::uint32_t>& out) {
  featureKeysScalar(p, n, points, normals, others, skip, keys, out);
}
#endif

void overlapFeatureKeysScalar(std::size_t i, std::size_t j0, const Points& points, const Points& normals,
                              const KeySpace& keys, std::vector<std::uint32_t>& out) {
  std::array<std::uint32_t, KeySpace::kMaxKeys> buf{};
  PairFeature f;
  for (std::size_t j = j0; j < points.size(); ++j) {
    if (j == i || !computeFeature(points[i], normals[i], points[j], normals[j], f)) continue;
    const int n = keys.overlapKeys(f, buf);
    out.insert(out.end(), buf.begin(), buf.begin() + n);
  }
}

#if defined(__x86_64__)
/// KeySpace::bins on 8 lanes: the bin (eq. 4) and the key's step to the neighbour bin (eq. 7):
/// -stride below, +stride above, 0 when there is none.
BINPOSE_AVX2_INLINE void bins8(__m256 value, __m256 step, int n_bins, __m256 overlap, __m256 upper_edge,
                               __m256i stride, __m256i& first, __m256i& side) {
  const __m256 scaled = _mm256_div_ps(value, step);
  first = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_floor_ps(scaled)), _mm256_set1_epi32(n_bins - 1));
  const __m256 frac = _mm256_sub_ps(scaled, _mm256_cvtepi32_ps(first));
  const __m256i lower = _mm256_and_si256(_mm256_castps_si256(_mm256_cmp_ps(frac, overlap, _CMP_LT_OQ)),
                                         _mm256_cmpgt_epi32(first, _mm256_setzero_si256()));
  const __m256i upper = _mm256_and_si256(_mm256_castps_si256(_mm256_cmp_ps(frac, upper_edge, _CMP_GT_OQ)),
                                         _mm256_cmpgt_epi32(_mm256_set1_epi32(n_bins - 1), first));
  side = _mm256_blendv_epi8(_mm256_and_si256(upper, stride), _mm256_sub_epi32(_mm256_setzero_si256(), stride), lower);
}

__attribute__((target("avx2"))) void overlapFeatureKeysAvx2(std::size_t i, const Points& points,
                                                            const Points& normals, const KeySpace& keys,
                                                            std::vector<std::uint32_t>& out) {
  const Point8 o = broadcast8(points[i], normals[i]);
  const QuantizationParams& qp = keys.params();
  const __m256 d_dist = _mm256_set1_ps(qp.d_dist), d_angle = _mm256_set1_ps(qp.d_angle);
  const __m256 d_limit = _mm256_set1_ps(qp.d_dist * static_cast<float>(keys.distanceBins()));
  const __m256 overlap = _mm256_set1_ps(qp.overlap), upper_edge = _mm256_set1_ps(1.0f - qp.overlap);
  const int nA = keys.angleBins(), nD = keys.distanceBins();
  const __m256i vnA = _mm256_set1_epi32(nA);
  const __m256i strides[4] = {_mm256_set1_epi32(nA * nA * nA), _mm256_set1_epi32(nA * nA), vnA, _mm256_set1_epi32(1)};
  alignas(32) std::int32_t key[8], side[4][8];
  std::uint32_t block[8 * KeySpace::kMaxKeys];  // one step's keys
  std::size_t j0 = 0;
  for (; j0 + 8 <= points.size(); j0 += 8) {
    const Features8 f = features8(o, points, normals, [&](int l) { return j0 + static_cast<std::size_t>(l); });
    const __m256 d = f.d;
    const __m256 value[4] = {d, f.theta1, f.theta2, f.theta3};
    // overlapKeys (eq. 4-7): the key of the four bins, and each dimension's step to its neighbour.
    __m256i k = _mm256_setzero_si256();
    for (int dim = 0; dim < 4; ++dim) {
      __m256i first, step;
      bins8(value[dim], dim == 0 ? d_dist : d_angle, dim == 0 ? nD : nA, overlap, upper_edge, strides[dim], first, step);
      k = dim == 0 ? first : _mm256_add_epi32(_mm256_mullo_epi32(k, vnA), first);
      _mm256_store_si256(reinterpret_cast<__m256i*>(side[dim]), step);
    }
    _mm256_store_si256(reinterpret_cast<__m256i*>(key), k);
    const __m256 kept = _mm256_and_ps(_mm256_cmp_ps(d, _mm256_setzero_ps(), _CMP_GT_OQ),
                                      _mm256_cmp_ps(d, d_limit, _CMP_LT_OQ));
    const auto defined = static_cast<unsigned>(_mm256_movemask_ps(kept));
    std::uint32_t* end = block;
    for (int l = 0; l < 8; ++l) {
      if (((defined >> l) & 1) == 0 || j0 + l == i) continue;
      // Doubling the list dimension by dimension, the last first, gives overlapKeys's order.
      std::uint32_t* start = end;
      *end++ = static_cast<std::uint32_t>(key[l]);
      for (int dim = 3; dim >= 0; --dim) {
        if (side[dim][l] == 0) continue;
        const auto step = static_cast<std::uint32_t>(side[dim][l]);
        for (std::uint32_t *from = start, *to = end; from != to;) *end++ = *from++ + step;
      }
    }
    out.insert(out.end(), block, end);
  }
  overlapFeatureKeysScalar(i, j0, points, normals, keys, out);
}
#else
void overlapFeatureKeysAvx2(std::size_t i, const Points& points, const Points& normals, const KeySpace& keys,
                            std::vector<std::uint32_t>& out) {
  overlapFeatureKeysScalar(i, 0, points, normals, keys, out);
}
#endif

}  // namespace

void overlapFeatureKeys(std::size_t i, const Points& points, const Points& normals, const KeySpace& keys,
                        std::vector<std::uint32_t>& out) {
  if (detail::haveAvx2()) overlapFeatureKeysAvx2(i, points, normals, keys, out);
  else overlapFeatureKeysScalar(i, 0, points, normals, keys, out);
}

void featureKeys(const Vec3& p, const Vec3& n, const Points& points, const Points& normals,
                 std::span<const std::uint32_t> others, std::uint32_t skip, const KeySpace& keys,
                 std::vector<std::uint32_t>& out) {
  if (detail::haveAvx2()) featureKeysAvx2(p, n, points, normals, others, skip, keys, out);
  else featureKeysScalar(p, n, points, normals, others, skip, keys, out);
}

}  // namespace binpose
