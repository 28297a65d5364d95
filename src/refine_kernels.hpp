#pragma once
// Internal: the SIMD kernels of ICP and the verification score (refine.cpp), each the lanes'
// version of a scalar loop there, summing in the very order the scalar code sums so that every
// lane is bit for bit the scalar result. refine.cpp runs whole blocks of four through them and
// the rest through its scalar code, which is the definition.
#include "oriented_lanes.hpp"

#include <binpose/types.hpp>

#include <bit>
#include <cstdint>
#include <vector>

#if defined(__SSE2__)
#include <immintrin.h>

namespace binpose::kernels {

/// The image frame's rotation on SIMD lanes: four points' image-frame coordinates and ranges,
/// summed as Eigen sums a 3 x 3 matrix times a vector, a + (b + c), and a norm,
/// sqrt(x^2 + (y^2 + z^2)) (both checked bit for bit against Eigen on 5 million random cases;
/// the other orders differed in 4-30% of them).
struct ViewLanes {
  __m128 t[3][3];
  explicit ViewLanes(const Eigen::Matrix3f& to_view) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) t[r][c] = _mm_set1_ps(to_view(r, c));
  }
  /// q = to_view d, for d = p - viewpoint.
  void rotate(const __m128 (&d)[3], __m128 (&q)[3]) const {
    for (int r = 0; r < 3; ++r)
      q[r] = _mm_add_ps(_mm_mul_ps(t[r][0], d[0]), _mm_add_ps(_mm_mul_ps(t[r][1], d[1]), _mm_mul_ps(t[r][2], d[2])));
  }
  static __m128 norm(const __m128 (&q)[3]) {
    return _mm_sqrt_ps(_mm_add_ps(_mm_mul_ps(q[0], q[0]), _mm_add_ps(_mm_mul_ps(q[1], q[1]), _mm_mul_ps(q[2], q[2]))));
  }
};

/// Four points of `lanes` from slot s posed (p = pose * m, n = pose.linear() * n_m) into p and n
/// (four x, then four y, then four z each), and a mask of those facing the viewpoint: the sums
/// of Eigen's products and of facesSensor() (a Transform times a vector sums its columns in
/// turn, ((R0 x + R1 y) + R2 z) + t; a matrix times a vector and a dot product sum a + (b + c)).
inline unsigned poseFour(const detail::OrientedLanes& lanes, std::size_t s, const Pose& pose, const Vec3& viewpoint, float* p,
                         float* n) {
  const Eigen::Matrix3f& R = pose.linear();
  const Vec3 t = pose.translation();
  const __m128 x = _mm_loadu_ps(lanes.c[0].data() + s), y = _mm_loadu_ps(lanes.c[1].data() + s), z = _mm_loadu_ps(lanes.c[2].data() + s);
  const __m128 a = _mm_loadu_ps(lanes.c[3].data() + s), b = _mm_loadu_ps(lanes.c[4].data() + s), c = _mm_loadu_ps(lanes.c[5].data() + s);
  __m128 w[3], m[3];
  for (int k = 0; k < 3; ++k) {
    const __m128 r0 = _mm_set1_ps(R(k, 0)), r1 = _mm_set1_ps(R(k, 1)), r2 = _mm_set1_ps(R(k, 2));
    const __m128 pk = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(r0, x), _mm_mul_ps(r1, y)), _mm_mul_ps(r2, z)), _mm_set1_ps(t[k]));
    m[k] = _mm_add_ps(_mm_mul_ps(r0, a), _mm_add_ps(_mm_mul_ps(r1, b), _mm_mul_ps(r2, c)));
    w[k] = _mm_sub_ps(_mm_set1_ps(viewpoint[k]), pk);
    _mm_storeu_ps(p + 4 * k, pk);
    _mm_storeu_ps(n + 4 * k, m[k]);
  }
  const __m128 dot = _mm_add_ps(_mm_mul_ps(m[0], w[0]), _mm_add_ps(_mm_mul_ps(m[1], w[1]), _mm_mul_ps(m[2], w[2])));
  return static_cast<unsigned>(_mm_movemask_ps(_mm_cmpgt_ps(dot, _mm_setzero_ps())));
}

/// The scan points' image directions and ranges (projectAll), whole blocks of four; returns the
/// number of points done.
template <class Out>
std::size_t projectBlocks(const Points& scan, const Vec3& viewpoint, const Eigen::Matrix3f& to_view, Out& out) {
  std::size_t i = 0;
  const ViewLanes view(to_view);
  for (; i + 4 <= scan.size(); i += 4) {
    const Vec3 *a = &scan[i], *b = &scan[i + 1], *c = &scan[i + 2], *e = &scan[i + 3];
    __m128 d[3], q[3];
    for (int k = 0; k < 3; ++k) d[k] = _mm_sub_ps(_mm_setr_ps((*a)[k], (*b)[k], (*c)[k], (*e)[k]), _mm_set1_ps(viewpoint[k]));
    view.rotate(d, q);
    const __m128 front = _mm_cmpnle_ps(q[2], _mm_setzero_ps());  // !(z <= 0), as the scalar test
    alignas(16) float u[4], v[4], range[4];
    _mm_store_ps(u, _mm_div_ps(q[0], q[2]));
    _mm_store_ps(v, _mm_div_ps(q[1], q[2]));
    _mm_store_ps(range, ViewLanes::norm(q));
    for (unsigned lanes = unsigned(_mm_movemask_ps(front)); lanes; lanes &= lanes - 1) {
      const int l = std::countr_zero(lanes);
      out.u.push_back(u[l]);
      out.v.push_back(v[l]);
      out.range.push_back(range[l]);
    }
  }
  return i;
}

/// The posed model's sensor-facing points (facingPoints), whole blocks of four lanes, each
/// handed to emit(p, n, range, u, v, grazing) in order; returns the number of points done.
template <class Emit>
std::size_t facingBlocks(const detail::OrientedLanes& lanes, const Pose& pose, const Vec3& viewpoint,
                         const Eigen::Matrix3f& to_view, float cos_grazing_angle, Emit&& emit) {
  const ViewLanes view(to_view);
  const __m128 cos_grazing = _mm_set1_ps(cos_grazing_angle);
  std::size_t s = 0;
  for (; s + 4 <= lanes.size; s += 4) {
    alignas(16) float pf[12], nf[12];
    unsigned keep = poseFour(lanes, s, pose, viewpoint, pf, nf);
    if (keep == 0) continue;
    __m128 w[3], d[3], n[3];
    for (int k = 0; k < 3; ++k) {
      const __m128 p = _mm_load_ps(pf + 4 * k), v = _mm_set1_ps(viewpoint[k]);
      w[k] = _mm_sub_ps(v, p);
      d[k] = _mm_sub_ps(p, v);
      n[k] = _mm_load_ps(nf + 4 * k);
    }
    __m128 q[3];
    view.rotate(d, q);
    keep &= static_cast<unsigned>(_mm_movemask_ps(_mm_cmpnle_ps(q[2], _mm_setzero_ps())));  // !(q.z <= 0)
    if (keep == 0) continue;
    const __m128 range = ViewLanes::norm(q);
    const __m128 dot = _mm_add_ps(_mm_mul_ps(n[0], w[0]), _mm_add_ps(_mm_mul_ps(n[1], w[1]), _mm_mul_ps(n[2], w[2])));
    const unsigned grazing = static_cast<unsigned>(_mm_movemask_ps(_mm_cmplt_ps(dot, _mm_mul_ps(cos_grazing, range))));
    alignas(16) float ranges[4], u[4], v[4];
    _mm_store_ps(ranges, range);
    _mm_store_ps(u, _mm_div_ps(q[0], q[2]));
    _mm_store_ps(v, _mm_div_ps(q[1], q[2]));
    for (; keep; keep &= keep - 1) {
      const int l = std::countr_zero(keep);
      emit(Vec3(pf[l], pf[4 + l], pf[8 + l]), Vec3(nf[l], nf[4 + l], nf[8 + l]), ranges[l], u[l], v[l], (grazing >> l & 1u) != 0);
    }
  }
  return s;
}

}  // namespace binpose::kernels
#endif

#if defined(__SSE4_1__)
namespace binpose::kernels {

/// Each point's cell of the image grid (u0, v0, bin; width x height cells) keeps the least range
/// (SceneEvidence's cellAt and minimum), whole blocks of four; returns the number of points done.
inline std::size_t nearestBlocks(const std::vector<float>& us, const std::vector<float>& vs, const std::vector<float>& ranges,
                                 float u0_, float v0_, float bin_, long width_, long height_, std::vector<float>& nearest_) {
  std::size_t i = 0;
  // cellAt on four points at a time: the same subtractions, divisions and floors.
  const __m128 u0 = _mm_set1_ps(u0_), v0 = _mm_set1_ps(v0_), bin = _mm_set1_ps(bin_), zero = _mm_setzero_ps();
  const __m128 width = _mm_set1_ps(float(width_)), height = _mm_set1_ps(float(height_));
  for (; i + 4 <= us.size(); i += 4) {
    const __m128 x = _mm_floor_ps(_mm_div_ps(_mm_sub_ps(_mm_loadu_ps(&us[i]), u0), bin));
    const __m128 y = _mm_floor_ps(_mm_div_ps(_mm_sub_ps(_mm_loadu_ps(&vs[i]), v0), bin));
    const __m128 inside = _mm_and_ps(_mm_and_ps(_mm_cmpge_ps(x, zero), _mm_cmplt_ps(x, width)),
                                     _mm_and_ps(_mm_cmpge_ps(y, zero), _mm_cmplt_ps(y, height)));
    alignas(16) std::int32_t cx[4], cy[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(cx), _mm_cvttps_epi32(x));
    _mm_store_si128(reinterpret_cast<__m128i*>(cy), _mm_cvttps_epi32(y));
    for (unsigned lanes = unsigned(_mm_movemask_ps(inside)); lanes; lanes &= lanes - 1) {
      const int l = std::countr_zero(lanes);
      float& cell = nearest_[std::size_t(long(cy[l]) * width_ + cx[l])];
      cell = std::min(cell, ranges[i + std::size_t(l)]);
    }
  }
  return i;
}

}  // namespace binpose::kernels
#endif
