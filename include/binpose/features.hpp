#pragma once
// Directed oriented point-pair features and their quantization (thesis 4.2, eq. 1-7).
#include <binpose/types.hpp>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace binpose {

/// F(m1, N1, m2, N2) = (d, theta1, theta2, theta3) (eq. 1-3): d = |m2 - m1|,
/// theta1 = angle(N1, m2 - m1), theta2 = angle(N2, m2 - m1), theta3 = angle(N1, N2), in radians.
struct PairFeature {
  float d = 0, theta1 = 0, theta2 = 0, theta3 = 0;
};

/// Angle between two vectors in [0, pi], accurate near 0 and pi (atan2 of |a x b| and a.b).
float angleBetween(const Vec3& a, const Vec3& b);

/// The feature of the directed pair (m1 -> m2). Normals must be unit vectors. False when the
/// points coincide (the feature is undefined).
bool computeFeature(const Vec3& m1, const Vec3& n1, const Vec3& m2, const Vec3& n2, PairFeature& f);

/// Quantization steps (eq. 4) and the overlap share p_d (eq. 7).
struct QuantizationParams {
  float d_dist = 1.0f;         ///< distance step d_dist, mm
  float d_angle = 0.13962634f; ///< angle step d_angle, radians (8 degrees, thesis 6.4)
  float overlap = 0.15f;       ///< p_d: a value within p_d * step of a bin edge also goes in the next bin
};

/// The dense key space of quantized features: key = ((mu_d * nA + mu_1) * nA + mu_2) * nA + mu_3.
class KeySpace {
 public:
  static constexpr std::uint32_t kInvalid = 0xFFFFFFFFu;
  static constexpr int kMaxKeys = 16;  ///< 2 choices in each of the 4 dimensions (eq. 7)

  KeySpace() = default;
  /// `max_distance`: the largest d that must have a key (the model's diameter).
  KeySpace(const QuantizationParams& params, float max_distance);

  [[nodiscard]] const QuantizationParams& params() const { return params_; }
  [[nodiscard]] int distanceBins() const { return n_dist_; }
  [[nodiscard]] int angleBins() const { return n_angle_; }
  [[nodiscard]] std::uint32_t size() const { return size_; }

  /// The one key of a feature by hard floor quantization (eq. 4-5), as used for scene features;
  /// kInvalid when d lies beyond the key space.
  [[nodiscard]] std::uint32_t key(const PairFeature& f) const;
  /// Every key of a model feature under the overlap rule (eq. 7) applied to the distance and to
  /// each angle: between 1 and 16 distinct keys written to `out`; returns how many.
  int overlapKeys(const PairFeature& f, std::array<std::uint32_t, kMaxKeys>& out) const;
  /// Bin and optional neighbour bin of one value (eq. 6-7); `second` is -1 when there is none.
  void bins(float value, float step, int n_bins, int& first, int& second) const;

 private:
  QuantizationParams params_;
  int n_dist_ = 0, n_angle_ = 0;
  std::uint32_t size_ = 0;
};

/// The scene side of eq. 1-5 for many pairs: for each index o of `others` but `skip`, in order,
/// the key (KeySpace::key) of the feature from (p, n) to (points[o], normals[o]), appended to
/// `out` (kInvalid beyond the key space; nothing when the points coincide). The same keys as
/// computeFeature and KeySpace::key one by one, 8 pairs to a step where the CPU has AVX2.
void featureKeys(const Vec3& p, const Vec3& n, const Points& points, const Points& normals,
                 std::span<const std::uint32_t> others, std::uint32_t skip, const KeySpace& keys,
                 std::vector<std::uint32_t>& out);

/// The model side of eq. 1-7 for every pair from point i: for each j of `points` but i, in
/// order, the keys KeySpace::overlapKeys gives the feature (i -> j), in its order, appended to
/// `out` (none when the points coincide or d lies beyond the key space). The same keys as
/// computeFeature and overlapKeys one pair at a time, 8 pairs to a step where the CPU has AVX2.
void overlapFeatureKeys(std::size_t i, const Points& points, const Points& normals, const KeySpace& keys,
                        std::vector<std::uint32_t>& out);

}  // namespace binpose
