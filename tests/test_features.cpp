// Point-pair features and their quantization (thesis 4.2, eq. 1-7).
#include <binpose/features.hpp>
#include <binpose/geometry.hpp>

#include "test_util.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

using namespace binpose;
using binpose::test::deg;

namespace {
constexpr float kPi = std::numbers::pi_v<float>;

PairFeature feature(Vec3 m1, Vec3 n1, Vec3 m2, Vec3 n2) {
  PairFeature f;
  EXPECT_TRUE(computeFeature(m1, n1.normalized(), m2, n2.normalized(), f));
  return f;
}

QuantizationParams thesisQuantization() {
  QuantizationParams q;
  q.d_dist = 1.0f;
  q.d_angle = 8.0f * kPi / 180.0f;
  q.overlap = 0.15f;
  return q;
}

/// `count` random oriented points, every tenth far enough out for some pairs to lie beyond a
/// 60 mm key space; point 17 at point 3's place, and normals 40 and 41 equal and opposite to
/// point 3's (theta3 = 0 and pi).
void batchTestPoints(int count, std::uint64_t seed, Points& points, Points& normals) {
  Rng rng(seed);
  for (int i = 0; i < count; ++i) {
    const float reach = i % 10 == 0 ? 90.0f : 40.0f;
    points.emplace_back(float(reach * rng.uniform()), float(reach * rng.uniform()), float(reach * rng.uniform()));
    normals.push_back(Vec3(float(rng.uniform() - 0.5), float(rng.uniform() - 0.5), float(rng.uniform() - 0.5)).normalized());
  }
  points[17] = points[3];
  normals[40] = normals[3];
  normals[41] = -normals[3];
}
}  // namespace

TEST(Feature, HandComputedPairs) {
  // Both normals up, the pair in the xy plane: a 3-4-5 triangle.
  PairFeature f = feature({0, 0, 0}, {0, 0, 1}, {3, 4, 0}, {0, 0, 1});
  EXPECT_NEAR(f.d, 5.0, 1e-6);
  EXPECT_NEAR(deg(f.theta1), 90.0, 1e-4);
  EXPECT_NEAR(deg(f.theta2), 90.0, 1e-4);
  EXPECT_NEAR(deg(f.theta3), 0.0, 1e-4);

  // n1 along x, n2 opposite, pair along the diagonal of the unit square.
  f = feature({0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0});
  EXPECT_NEAR(f.d, std::sqrt(2.0), 1e-6);
  EXPECT_NEAR(deg(f.theta1), 45.0, 1e-4);
  EXPECT_NEAR(deg(f.theta2), 135.0, 1e-4);
  EXPECT_NEAR(deg(f.theta3), 180.0, 1e-4);

  // Three mutually perpendicular directions.
  f = feature({1, 2, 3}, {1, 0, 0}, {1, 2, 5}, {0, 1, 0});
  EXPECT_NEAR(f.d, 2.0, 1e-6);
  EXPECT_NEAR(deg(f.theta1), 90.0, 1e-4);
  EXPECT_NEAR(deg(f.theta2), 90.0, 1e-4);
  EXPECT_NEAR(deg(f.theta3), 90.0, 1e-4);

  // A 60 degree case: n1 = (1, 0, 0), d along (1, sqrt(3), 0)/2 * 4.
  f = feature({0, 0, 0}, {1, 0, 0}, {2, 2 * std::sqrt(3.0f), 0}, {0, 0, -1});
  EXPECT_NEAR(f.d, 4.0, 1e-5);
  EXPECT_NEAR(deg(f.theta1), 60.0, 1e-3);
  EXPECT_NEAR(deg(f.theta2), 90.0, 1e-3);
  EXPECT_NEAR(deg(f.theta3), 90.0, 1e-3);
}

TEST(Feature, IsDirected) {
  // F(m2 -> m1) has theta1' = pi - theta2 and theta2' = pi - theta1 (d reverses).
  Rng rng(7);
  for (int trial = 0; trial < 100; ++trial) {
    auto rnd = [&] { return Vec3(float(rng.uniform() - 0.5), float(rng.uniform() - 0.5), float(rng.uniform() - 0.5)); };
    const Vec3 m1 = 50 * rnd(), m2 = 50 * rnd(), n1 = rnd().normalized(), n2 = rnd().normalized();
    PairFeature a, b;
    ASSERT_TRUE(computeFeature(m1, n1, m2, n2, a));
    ASSERT_TRUE(computeFeature(m2, n2, m1, n1, b));
    EXPECT_NEAR(a.d, b.d, 1e-4);
    EXPECT_NEAR(b.theta1, kPi - a.theta2, 1e-4);
    EXPECT_NEAR(b.theta2, kPi - a.theta1, 1e-4);
    EXPECT_NEAR(a.theta3, b.theta3, 1e-4);
  }
}

TEST(Feature, CoincidentPointsHaveNoFeature) {
  PairFeature f;
  EXPECT_FALSE(computeFeature({1, 1, 1}, {0, 0, 1}, {1, 1, 1}, {0, 1, 0}, f));
}

TEST(Quantization, BinsAtEdges) {
  const KeySpace keys(thesisQuantization(), 60.0f);
  int a, b;
  keys.bins(2.5f, 1.0f, keys.distanceBins(), a, b);  // mid-bin: one bin
  EXPECT_EQ(a, 2); EXPECT_EQ(b, -1);
  keys.bins(2.1f, 1.0f, keys.distanceBins(), a, b);  // 0.1 above the edge at 2 (< 0.15): also bin 1
  EXPECT_EQ(a, 2); EXPECT_EQ(b, 1);
  keys.bins(2.9f, 1.0f, keys.distanceBins(), a, b);  // 0.1 below the edge at 3: also bin 3
  EXPECT_EQ(a, 2); EXPECT_EQ(b, 3);
  keys.bins(2.16f, 1.0f, keys.distanceBins(), a, b);  // just outside the overlap band
  EXPECT_EQ(a, 2); EXPECT_EQ(b, -1);
  keys.bins(0.05f, 1.0f, keys.distanceBins(), a, b);  // no bin below 0
  EXPECT_EQ(a, 0); EXPECT_EQ(b, -1);
  const float step = 8.0f * kPi / 180.0f;
  keys.bins(kPi, step, keys.angleBins(), a, b);  // 180 deg = 22.5 steps: bin 22, mid-bin
  EXPECT_EQ(keys.angleBins(), 23);
  EXPECT_EQ(a, 22); EXPECT_EQ(b, -1);
  keys.bins(176.5f * kPi / 180.0f, step, keys.angleBins(), a, b);  // 22.06 steps: also 21
  EXPECT_EQ(a, 22); EXPECT_EQ(b, 21);
  keys.bins(175.5f * kPi / 180.0f, step, keys.angleBins(), a, b);  // 21.94 steps: also 22
  EXPECT_EQ(a, 21); EXPECT_EQ(b, 22);
}

TEST(Quantization, OverlapKeysCountAndDistinct) {
  const KeySpace keys(thesisQuantization(), 60.0f);
  std::array<std::uint32_t, KeySpace::kMaxKeys> out{};
  const float deg8 = 8.0f * kPi / 180.0f;
  // every dimension in an overlap band: 2^4 keys
  PairFeature f{10.05f, 3.05f * deg8, 5.95f * deg8, 7.1f * deg8};
  ASSERT_EQ(keys.overlapKeys(f, out), 16);
  std::vector<std::uint32_t> v(out.begin(), out.begin() + 16);
  std::sort(v.begin(), v.end());
  EXPECT_EQ(std::unique(v.begin(), v.end()), v.end());
  // none in a band: exactly the hard key
  f = {10.5f, 3.5f * deg8, 5.5f * deg8, 7.5f * deg8};
  ASSERT_EQ(keys.overlapKeys(f, out), 1);
  EXPECT_EQ(out[0], keys.key(f));
  // two dimensions in a band
  f = {10.95f, 3.5f * deg8, 5.1f * deg8, 7.5f * deg8};
  EXPECT_EQ(keys.overlapKeys(f, out), 4);
}

TEST(Quantization, PerturbedSceneKeyIsAmongModelKeys) {
  // The point of eq. 7: a scene feature within p_d of a step of the model's value, in every
  // dimension, must hash to one of the model's keys.
  const QuantizationParams q = thesisQuantization();
  const KeySpace keys(q, 60.0f);
  Rng rng(11);
  std::array<std::uint32_t, KeySpace::kMaxKeys> out{};
  int misses = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const PairFeature m{float(1 + 55 * rng.uniform()), float(kPi * rng.uniform()), float(kPi * rng.uniform()),
                        float(kPi * rng.uniform())};
    auto jitter = [&](float v, float step, float hi) {
      return std::clamp(v + float((2 * rng.uniform() - 1) * 0.99 * q.overlap) * step, 0.0f, hi);
    };
    const PairFeature s{jitter(m.d, q.d_dist, 60.0f), jitter(m.theta1, q.d_angle, kPi), jitter(m.theta2, q.d_angle, kPi),
                        jitter(m.theta3, q.d_angle, kPi)};
    const int n = keys.overlapKeys(m, out);
    if (std::find(out.begin(), out.begin() + n, keys.key(s)) == out.begin() + n) ++misses;
  }
  EXPECT_EQ(misses, 0);
}

TEST(Quantization, OutOfRangeAndBadParameters) {
  const KeySpace keys(thesisQuantization(), 60.0f);
  EXPECT_EQ(keys.key({1000.0f, 0, 0, 0}), KeySpace::kInvalid);
  std::array<std::uint32_t, KeySpace::kMaxKeys> out{};
  EXPECT_EQ(keys.overlapKeys({1000.0f, 0, 0, 0}, out), 0);
  QuantizationParams bad = thesisQuantization();
  bad.d_dist = 0;
  EXPECT_THROW(KeySpace(bad, 60.0f), Error);
  bad = thesisQuantization();
  bad.overlap = 0.5f;
  EXPECT_THROW(KeySpace(bad, 60.0f), Error);
  bad = thesisQuantization();
  bad.d_dist = 1e-4f;  // absurdly fine: billions of keys
  EXPECT_THROW(KeySpace(bad, 60.0f), Error);
  EXPECT_THROW(KeySpace(thesisQuantization(), std::nanf("")), Error);
}

TEST(Quantization, SceneKeysInBatchesAreTheKeysOneByOne) {
  // featureKeys (8 pairs to a SIMD step) against computeFeature and key one pair at a time: the
  // same keys in the same order, the voter itself skipped, a partner at the voter's place left
  // out, pairs beyond the key space kInvalid, and a count not a multiple of 8.
  const KeySpace keys(thesisQuantization(), 60.0f);
  Points points, normals;
  batchTestPoints(203, 5, points, normals);
  std::vector<std::uint32_t> others(points.size());
  std::iota(others.begin(), others.end(), 0u);
  std::reverse(others.begin(), others.end());
  int invalid = 0;
  for (const std::uint32_t k : {3u, 40u, 150u}) {
    for (const std::size_t count : {others.size(), std::size_t{13}, std::size_t{5}}) {
      const auto some = std::span<const std::uint32_t>(others).first(count);
      std::vector<std::uint32_t> expected, got;
      for (const std::uint32_t o : some) {
        PairFeature f;
        if (o != k && computeFeature(points[k], normals[k], points[o], normals[o], f)) expected.push_back(keys.key(f));
      }
      featureKeys(points[k], normals[k], points, normals, some, k, keys, got);
      EXPECT_EQ(got, expected) << k << " " << count;
      invalid += static_cast<int>(std::count(got.begin(), got.end(), KeySpace::kInvalid));
    }
  }
  std::vector<std::uint32_t> all;
  featureKeys(points[3], normals[3], points, normals, others, 3, keys, all);
  EXPECT_EQ(all.size(), points.size() - 2);  // neither point 3 itself nor point 17 at its place
  EXPECT_GT(invalid, 0);
}

TEST(Quantization, ModelKeysInBatchesAreTheOverlapKeysOneByOne) {
  // overlapFeatureKeys (8 pairs to a SIMD step) against computeFeature and overlapKeys one pair
  // at a time: the same keys in the same order, the point itself skipped, a point at its place
  // left out, pairs beyond the key space without keys, and a count not a multiple of 8.
  const KeySpace keys(thesisQuantization(), 60.0f);
  Points points, normals;
  batchTestPoints(205, 7, points, normals);
  std::size_t beyond = 0, overlapping = 0;
  for (const std::size_t i : {std::size_t{0}, std::size_t{3}, std::size_t{40}, std::size_t{204}}) {
    std::vector<std::uint32_t> expected, got;
    std::array<std::uint32_t, KeySpace::kMaxKeys> buf{};
    for (std::size_t j = 0; j < points.size(); ++j) {
      PairFeature f;
      if (j == i || !computeFeature(points[i], normals[i], points[j], normals[j], f)) continue;
      const int n = keys.overlapKeys(f, buf);
      beyond += n == 0;
      overlapping += n > 1;
      expected.insert(expected.end(), buf.begin(), buf.begin() + n);
    }
    overlapFeatureKeys(i, points, normals, keys, got);
    EXPECT_EQ(got, expected) << i;
  }
  EXPECT_GT(beyond, 0u);
  EXPECT_GT(overlapping, 100u);
}
