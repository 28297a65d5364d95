// Background planes (planes.hpp): the bin's floor and walls go, parts' faces stay.
#include <binpose/geometry.hpp>
#include <binpose/planes.hpp>

#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>

using namespace binpose;

namespace {

constexpr float kSpacing = 4.0f;  // mm between samples: density 1/16 points per mm^2

/// A bin seen from a sensor at the origin looking along +z: a floor at z = 500 and a wall at
/// x = 100 (both facing the sensor), three flat parts touching side by side with their tops at
/// z = 480 (a connected, coplanar layer of 3 x 2463 mm^2), and one small flat top at z = 450.
struct Bin {
  Points points, normals;
  std::vector<int> kind;  // 0 floor, 1 wall, 2 layer of part tops, 3 small top
  void add(const Vec3& p, const Vec3& n, int k, Rng& rng) {
    points.push_back(p + n * (0.2f * test::gaussian(rng)));  // 0.2 mm noise along the normal
    normals.push_back(n);
    kind.push_back(k);
  }
};

bool onDisc(float x, float y) {
  for (const float cx : {-56.0f, 0.0f, 56.0f})
    if ((x - cx) * (x - cx) + y * y <= 28.0f * 28.0f) return true;
  return false;
}

Bin makeBin() {
  Bin bin;
  Rng rng(3);
  for (float x = -100; x <= 100; x += kSpacing)
    for (float y = -100; y <= 100; y += kSpacing) {
      if (onDisc(x, y)) bin.add(Vec3(x, y, 480), Vec3(0, 0, -1), 2, rng);  // the floor beneath is hidden
      else if (std::abs(x + 70) <= 20 && std::abs(y - 70) <= 20) bin.add(Vec3(x, y, 450), Vec3(0, 0, -1), 3, rng);
      else bin.add(Vec3(x, y, 500), Vec3(0, 0, -1), 0, rng);
    }
  for (float z = 400; z < 500; z += kSpacing)
    for (float y = -100; y <= 100; y += kSpacing) bin.add(Vec3(100, y, z), Vec3(-1, 0, 0), 1, rng);
  return bin;
}

/// Points of each kind, and those of each kind taken out as a plane's.
struct Tally {
  int count[4] = {0, 0, 0, 0}, removed[4] = {0, 0, 0, 0};
};

Tally tally(const Bin& bin, const std::vector<char>& flat) {
  Tally t;
  for (std::size_t i = 0; i < flat.size(); ++i) {
    ++t.count[bin.kind[i]];
    t.removed[bin.kind[i]] += flat[i];
  }
  return t;
}

}  // namespace

TEST(Planes, FloorAndWallGoTheLayerOfPartsStays) {
  const Bin bin = makeBin();
  const std::vector<char> flat = largePlanes(bin.points, bin.normals, 1.0f / (kSpacing * kSpacing), PlaneParams{});
  ASSERT_EQ(flat.size(), bin.points.size());
  const auto [count, removed] = tally(bin, flat);
  EXPECT_GE(removed[0], 0.99 * count[0]) << "floor";
  EXPECT_GE(removed[1], 0.99 * count[1]) << "wall";
  EXPECT_GT(count[2] * kSpacing * kSpacing, 6000.0f) << "the layer is larger than min_area: only the floor behind it saves it";
  EXPECT_EQ(removed[2], 0) << "layer of part tops";
  EXPECT_EQ(removed[3], 0) << "small top";
}

// Three plates 4 mm thick lying flat on the floor, touching (brackets' plates): their tops form a
// plane larger than min_area that hides nothing farther than 3 tolerances behind it, parallel to
// the floor. They lie in the floor's holes, less than a part's size above it: parts, not a second
// floor. Neither their points nor their plane (what verification counts as solid) are taken.
TEST(Planes, PlatesLyingFlatOnTheFloorStay) {
  Bin bin;
  Rng rng(7);
  for (float x = -100; x <= 100; x += kSpacing)
    for (float y = -100; y <= 100; y += kSpacing) {
      if (onDisc(x, y)) bin.add(Vec3(x, y, 496), Vec3(0, 0, -1), 2, rng);
      else bin.add(Vec3(x, y, 500), Vec3(0, 0, -1), 0, rng);
    }
  PlaneParams params;
  params.hole = 60.0f;  // what a part lying on the floor hides of it (StageSettings: the part's size)
  std::vector<Plane> background;
  const std::vector<char> flat = largePlanes(bin.points, bin.normals, 1.0f / (kSpacing * kSpacing), params, &background);
  const auto [count, removed] = tally(bin, flat);
  EXPECT_GT(count[2] * kSpacing * kSpacing, params.min_area) << "the plates' tops are larger than min_area";
  EXPECT_GE(removed[0], 0.99 * count[0]) << "floor";
  EXPECT_EQ(removed[2], 0) << "plates";
  ASSERT_EQ(background.size(), 1u) << "the floor alone";
  EXPECT_NEAR(background[0].normal.z() * background[0].d, 500.0f, 0.2f);
}

// Six caps lying open side up on the floor: their insides are discs 3 mm above it, each smaller
// than min_area and apart from the others, together a plane larger than min_area. That plane
// hides the floor seen between the discs, 2 tolerances behind it: a layer of parts, not a second
// floor, though nothing lies 3 tolerances behind it. Its points and plane stay.
TEST(Planes, InsidesOfCapsOpenSideUpStay) {
  Bin bin;
  Rng rng(9);
  auto inDisc = [](float x, float y) {
    for (const float cx : {-66.0f, 0.0f, 66.0f})
      for (const float cy : {-33.0f, 33.0f})
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= 26.0f * 26.0f) return true;
    return false;
  };
  for (float x = -100; x <= 100; x += kSpacing)
    for (float y = -70; y <= 70; y += kSpacing) {
      if (inDisc(x, y)) bin.add(Vec3(x, y, 497), Vec3(0, 0, -1), 2, rng);
      else bin.add(Vec3(x, y, 500), Vec3(0, 0, -1), 0, rng);
    }
  std::vector<Plane> background;
  const std::vector<char> flat = largePlanes(bin.points, bin.normals, 1.0f / (kSpacing * kSpacing), PlaneParams{}, &background);
  const auto [count, removed] = tally(bin, flat);
  EXPECT_GT(count[2] * kSpacing * kSpacing, PlaneParams{}.min_area) << "the discs together are larger than min_area";
  EXPECT_GE(removed[0], 0.99 * count[0]) << "floor";
  EXPECT_EQ(removed[2], 0) << "discs";
  ASSERT_EQ(background.size(), 1u) << "the floor alone";
  EXPECT_NEAR(background[0].normal.z() * background[0].d, 500.0f, 0.2f);
}

TEST(Planes, ASmallFlatTopAloneStays) {
  const Bin bin = makeBin();
  Bin parts;
  for (std::size_t i = 0; i < bin.points.size(); ++i)
    if (bin.kind[i] == 3) {
      parts.points.push_back(bin.points[i]);
      parts.normals.push_back(bin.normals[i]);
      parts.kind.push_back(3);
    }
  const std::vector<char> flat = largePlanes(parts.points, parts.normals, 1.0f / (kSpacing * kSpacing), PlaneParams{});
  EXPECT_EQ(std::count(flat.begin(), flat.end(), 1), 0) << "a 1600 mm^2 top is below min_area";
}

TEST(Planes, ATiltedFaceThatHidesNothingStays) {
  // A floor at z = 500 and a 100 x 100 mm plate tilted 40 degrees above it (a part's large
  // face), the floor points under the plate (along its normal) left out: nothing lies behind
  // the plate within its extent, so only its tilt tells it from the bin.
  const float tilt = 40.0f * float(M_PI) / 180.0f;
  const Vec3 centre(0, 0, 440), n(0, std::sin(tilt), -std::cos(tilt)), u = Vec3::UnitX(), v = n.cross(u);
  Bin bin;
  Rng rng(5);
  for (float a = -50; a <= 50; a += kSpacing)
    for (float b = -50; b <= 50; b += kSpacing) bin.add(centre + a * u + b * v, n, 2, rng);
  for (float x = -150; x <= 150; x += kSpacing)
    for (float y = -150; y <= 150; y += kSpacing) {
      const Vec3 p(x, y, 500);
      if (std::abs(u.dot(p - centre)) <= 52 && std::abs(v.dot(p - centre)) <= 52) continue;  // under the plate
      bin.add(p, Vec3(0, 0, -1), 0, rng);
    }
  std::vector<Plane> background;
  const std::vector<char> flat = largePlanes(bin.points, bin.normals, 1.0f / (kSpacing * kSpacing), PlaneParams{}, &background);
  const auto [count, removed] = tally(bin, flat);
  EXPECT_GT(count[2] * kSpacing * kSpacing, PlaneParams{}.min_area) << "the plate is larger than min_area";
  EXPECT_GE(removed[0], 0.99 * count[0]) << "floor";
  EXPECT_EQ(removed[2], 0) << "tilted plate";
  ASSERT_EQ(background.size(), 1u);
  EXPECT_GT(std::abs(background[0].normal.z()), 0.999f);
}

// A table seen from in front of it, the sensor not above it: past its near edge the sensor sees
// the floor 700 mm below, under the table. Those floor points lie behind the table within its
// extent, as the floor under a layer of parts does, but their line of sight crosses the table's
// plane off the table: it hides nothing seen through it, and it is the largest plane. Both the
// table and the floor go.
TEST(Planes, ATableWithTheFloorSeenUnderItsNearEdgeGoes) {
  const Vec3 sensor(-300, 0, 0), up(0, 0, -1);
  Bin scene;
  Rng rng(11);
  for (float x = 0; x <= 200; x += kSpacing)  // the table, z = 500: 200 x 200 mm
    for (float y = -100; y <= 100; y += kSpacing) scene.add(Vec3(x, y, 500), up, 0, rng);
  const auto hidden = [&](const Vec3& p) {  // behind the table, as the sensor sees it
    const Vec3 c = sensor + (500.0f / p.z()) * (p - sensor);
    return c.x() >= 0 && c.x() <= 200 && std::abs(c.y()) <= 100;
  };
  for (float x = -100; x <= 300; x += 8.0f)  // the floor, z = 1200, sparser (farther)
    for (float y = -150; y <= 150; y += 8.0f)
      if (!hidden(Vec3(x, y, 1200))) scene.add(Vec3(x, y, 1200), up, 1, rng);
  PlaneParams params;
  params.viewpoint = sensor;
  std::vector<Plane> background;
  const std::vector<char> flat = largePlanes(scene.points, scene.normals, 1.0f / (kSpacing * kSpacing), params, &background);
  int count[2] = {0, 0}, removed[2] = {0, 0}, under = 0;
  for (std::size_t i = 0; i < flat.size(); ++i) {
    ++count[scene.kind[i]];
    removed[scene.kind[i]] += flat[i];
    under += scene.kind[i] == 1 && scene.points[i].x() >= 0 && scene.points[i].x() <= 200 && std::abs(scene.points[i].y()) <= 100;
  }
  EXPECT_GT(under, static_cast<int>(0.02 * double(flat.size()))) << "enough floor under the table to fail the extent test";
  EXPECT_GE(removed[0], 0.99 * count[0]) << "table";
  EXPECT_GE(removed[1], 0.99 * count[1]) << "floor";
  EXPECT_EQ(background.size(), 2u);
}

TEST(Planes, SameResultForTheSameSeed) {
  const Bin bin = makeBin();
  const float density = 1.0f / (kSpacing * kSpacing);
  EXPECT_EQ(largePlanes(bin.points, bin.normals, density, PlaneParams{}),
            largePlanes(bin.points, bin.normals, density, PlaneParams{}));
}

TEST(Planes, AbsurdInputIsRefused) {
  const Bin bin = makeBin();
  EXPECT_THROW((void)largePlanes(bin.points, bin.normals, 0.0f, PlaneParams{}), Error);
  PlaneParams bad;
  bad.tolerance = -1;
  EXPECT_THROW((void)largePlanes(bin.points, bin.normals, 0.0625f, bad), Error);
  Points fewer(bin.normals.begin(), bin.normals.end() - 1);
  EXPECT_THROW((void)largePlanes(bin.points, fewer, 0.0625f, PlaneParams{}), Error);
  EXPECT_TRUE(largePlanes({}, {}, 0.0625f, PlaneParams{}).empty());
  // Late normals without their flags, or with too few.
  LateNormals late;
  late.finish = [](std::span<const std::uint32_t>) {};
  late.aligned = [](std::uint32_t, const Vec3&, float) { return -1; };
  EXPECT_THROW((void)largePlanes(bin.points, bin.normals, 0.0625f, PlaneParams{}, nullptr, &late), Error);
  const std::vector<char> short_flags(bin.points.size() - 1, 0);
  late.pending = &short_flags;
  EXPECT_THROW((void)largePlanes(bin.points, bin.normals, 0.0625f, PlaneParams{}, nullptr, &late), Error);
  // With none pending, the same flags as without.
  const std::vector<char> none(bin.points.size(), 0);
  late.pending = &none;
  EXPECT_EQ(largePlanes(bin.points, bin.normals, 0.0625f, PlaneParams{}, nullptr, &late),
            largePlanes(bin.points, bin.normals, 0.0625f, PlaneParams{}));
}

// A plane's inliers are split into patches joined by links shorter than PlaneParams::link
// (10 mm), and only a patch of min_area goes. Two strips of a tilted plane (4000 mm^2 each,
// 8000 together against a min_area of 6000), a gap between them: 9.5 mm joins them and both go,
// 10.5 mm leaves two patches too small to go.
TEST(Planes, PatchesJoinAcrossGapsShorterThanTheLink) {
  const Vec3 e1(1, 0, 0), e2(0, 0.8f, 0.6f), normal(0, 0.6f, -0.8f), origin(-50, -40, 500);
  for (const float gap : {9.5f, 10.5f}) {
    Points points, normals;
    for (float u = 0; u <= 100; u += kSpacing)
      for (const float start : {0.0f, 40.0f + gap})
        for (float v = 0; v <= 40; v += kSpacing) {
          points.push_back(origin + u * e1 + (start + v) * e2);
          normals.push_back(normal);
        }
    const std::vector<char> flat = largePlanes(points, normals, 1.0f / (kSpacing * kSpacing), PlaneParams{});
    const auto removed = std::count(flat.begin(), flat.end(), 1);
    if (gap < PlaneParams{}.link)
      EXPECT_EQ(removed, static_cast<long>(points.size())) << "gap " << gap;
    else
      EXPECT_EQ(removed, 0) << "gap " << gap;
  }
}

// The patches are the connected components of "strictly closer than link" by definition (every
// pair, a union-find), on clouds that reach both of linkedPatches's paths: lattices on a plane,
// flat or shaken off it by up to 0.3 links, given its normal or one at random (cells along the
// plane), and clusters spread far wider than the link or given a normal across a thick slab (the
// grid's flood fill). The lattices' spacing is the link or a float's step under it, or less, so
// pairs at the threshold count; a quarter of the clouds are points at random on the plane, sparser.
TEST(Planes, PatchesAreTheComponentsOfTheLinks) {
  Rng rng(7);
  const auto randomUnit = [&] { return Vec3(test::gaussian(rng), test::gaussian(rng), test::gaussian(rng)).normalized(); };
  int split = 0, large = 0;  // trials of several patches, and of a patch over 50 points
  for (int trial = 0; trial < 60; ++trial) {
    const float link = 2.0f + 8.0f * static_cast<float>(rng.uniform());
    const bool stretched = trial % 3 == 2;
    Points points;
    std::vector<std::uint32_t> members;
    const int clusters = 1 + trial % 5;
    Vec3 normal = randomUnit();
    const Vec3 u = trial % 2 ? Vec3::UnitX() : normal.unitOrthogonal(), v = trial % 2 ? Vec3::UnitY() : normal.cross(u);
    for (int c = 0; c < clusters; ++c) {
      const auto spread = [&] { return static_cast<float>(120.0 * rng.uniform() - 60.0); };
      const Vec3 centre = Vec3(0, 0, 500) + (stretched ? Vec3(float(c) * 1e6f, 0, 0) : spread() * u + spread() * v);
      const float step = trial % 4 == 0 ? link : trial % 4 == 1 ? std::nextafter(link, 0.0f) : 0.7f * link;
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) {
          if (rng.uniform() < 0.15) continue;  // holes that may cut a lattice apart
          Vec3 p = centre + (float(i) * step) * u + (float(j) * step) * v;
          if (trial % 4 == 3) p += 0.3f * link * randomUnit();
          if (trial % 8 == 2 || trial % 8 == 6)  // at random over the lattice's square instead
            p = centre + float(20.0 * step * rng.uniform()) * u + float(20.0 * step * rng.uniform()) * v;
          points.push_back(p);
        }
    }
    for (std::uint32_t i = 0; i < points.size(); ++i)
      if (rng.uniform() < 0.9) members.push_back(i);
    // By definition: every pair, in float, strictly under link^2.
    std::vector<std::uint32_t> parent(members.size());
    std::iota(parent.begin(), parent.end(), 0u);
    auto root = [&](std::uint32_t a) {
      while (parent[a] != a) a = parent[a];
      return a;
    };
    for (std::uint32_t a = 0; a < members.size(); ++a)
      for (std::uint32_t b = a + 1; b < members.size(); ++b) {
        const Vec3 d = points[members[b]] - points[members[a]];
        if (d.x() * d.x() + (d.y() * d.y() + d.z() * d.z()) < link * link) parent[std::max(root(a), root(b))] = std::min(root(a), root(b));
      }
    std::vector<std::vector<std::uint32_t>> expected;
    std::vector<int> patch_of(members.size(), -1);
    for (std::uint32_t k = 0; k < members.size(); ++k) {
      int& p = patch_of[root(k)];
      if (p < 0) {
        p = static_cast<int>(expected.size());
        expected.emplace_back();
      }
      expected[static_cast<std::size_t>(p)].push_back(members[k]);
    }
    if (trial % 2) normal = Vec3::UnitZ();
    if (trial % 5 == 4) normal = randomUnit();  // not the plane's
    auto found = detail::linkedPatches(points, members, link, normal);
    for (auto& patch : found) std::sort(patch.begin(), patch.end());
    EXPECT_EQ(found, expected) << "trial " << trial << ", link " << link;
    split += expected.size() > 1;
    large += std::any_of(expected.begin(), expected.end(), [](const auto& p) { return p.size() > 50; });
  }
  EXPECT_GT(split, 20);
  EXPECT_GT(large, 20);
}

// Two points near the link's distance apart, along a plane and a little across it: one patch
// exactly when they are closer than the link (in float, the definition's sum), wherever the
// cells along the plane put them.
TEST(Planes, APairIsOnePatchExactlyWhenLinked) {
  Rng rng(11);
  const auto randomUnit = [&] { return Vec3(test::gaussian(rng), test::gaussian(rng), test::gaussian(rng)).normalized(); };
  int linked = 0, apart = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const float link = 1.0f + 9.0f * static_cast<float>(rng.uniform());
    const Vec3 normal = randomUnit(), along = normal.cross(randomUnit()).normalized();
    const Vec3 p = 300.0f * randomUnit() + Vec3(0, 0, 600);
    const float across = static_cast<float>(0.6 * rng.uniform() - 0.3) * link;
    const Points points{p, p + static_cast<float>(0.9 + 0.2 * rng.uniform()) * link * along + across * normal};
    const Vec3 d = points[1] - points[0];
    const bool close = d.x() * d.x() + (d.y() * d.y() + d.z() * d.z()) < link * link;
    (close ? linked : apart) += 1;
    EXPECT_EQ(detail::linkedPatches(points, {0, 1}, link, normal).size(), close ? 1u : 2u) << "trial " << trial;
  }
  EXPECT_GT(linked, 5000);
  EXPECT_GT(apart, 5000);
}

// A wide floor under a Kinect-class sensor's noise (2 mm along the line of sight), bent by 3 mm
// from its middle to its edges as such a sensor's depth is, whose normals are as rough as such a
// scan's (each tilted by up to 20 degrees): a hypothesis drawn from one point's normal cuts a
// tilted band out of it, and only refitting the band's plane until its inliers stop growing
// takes the whole floor as one plane, level.
TEST(Planes, ANoisyFloorWithRoughNormalsIsFoundWholeAndLevel) {
  Rng rng(5);
  Points points, normals;
  for (float x = -300; x <= 300; x += kSpacing)
    for (float y = -300; y <= 300; y += kSpacing) {
      points.push_back(Vec3(x, y, 900 + 3.0f * (x * x + y * y) / (2 * 300 * 300) + 2.0f * test::gaussian(rng)));
      const float tilt = 0.35f * static_cast<float>(rng.uniform()), turn = 6.2831853f * static_cast<float>(rng.uniform());
      normals.push_back(Vec3(std::sin(tilt) * std::cos(turn), std::sin(tilt) * std::sin(turn), -std::cos(tilt)));
    }
  PlaneParams params;
  params.tolerance = 2.3f * 2.0f;  // the noise-adapted plane tolerance (noise.cpp)
  params.max_angle = 0.45f;
  std::vector<Plane> found;
  const std::vector<char> flat = largePlanes(points, normals, 1.0f / (kSpacing * kSpacing), params, &found);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_GT(std::abs(found[0].normal.z()), std::cos(0.5f * 3.14159265f / 180.0f));  // within half a degree of level
  EXPECT_NEAR(std::abs(found[0].d), 901.0f, 1.0f);
  const auto on = std::count(flat.begin(), flat.end(), 1);
  EXPECT_GT(on, static_cast<long>(0.9 * static_cast<double>(points.size())));
}

// The extent bridges a hole that a part lying on the floor leaves in it, but neither the inside
// of a bin's rim (a ring of the same plane) nor what lies off the plane's edge.
TEST(PlaneFootprint, BridgesAPartsHoleButNotTheInsideOfARim) {
  const Plane level{Vec3::UnitZ(), 0.0f, {}};
  Points floor, rim;
  for (float x = -150; x <= 150; x += 2)
    for (float y = -150; y <= 150; y += 2) {
      if (std::abs(x) > 20 || std::abs(y) > 30) floor.emplace_back(x, y, 0.0f);  // a 40 x 60 mm hole
      if (std::abs(x) > 130 || std::abs(y) > 130) rim.emplace_back(x, y, 0.0f);   // a 20 mm wide ring
    }
  const auto all = [](const Points& p) {
    std::vector<std::uint32_t> i(p.size());
    std::iota(i.begin(), i.end(), 0u);
    return i;
  };
  const PlaneFootprint on_floor(floor, all(floor), level, 6.0f, 60.0f), on_rim(rim, all(rim), level, 6.0f, 60.0f);
  EXPECT_TRUE(on_floor.covers(Vec3(100, 100, -30)));  // on it, a point below it
  EXPECT_TRUE(on_floor.covers(Vec3(0, 0, -30)));      // in the hole
  EXPECT_FALSE(on_floor.covers(Vec3(200, 0, -30)));   // off its edge
  EXPECT_TRUE(on_rim.covers(Vec3(140, 0, -30)));
  EXPECT_FALSE(on_rim.covers(Vec3(0, 0, -30)));       // inside the bin
  EXPECT_FALSE(on_rim.covers(Vec3(90, 90, -30)));     // near its inner corner
  EXPECT_NEAR(on_floor.area(), 300.0 * 300.0 - 40.0 * 60.0, 0.1 * 300.0 * 300.0);
}

// Six caps lying open side up on a floor, touching: their insides, 3 mm above the floor, show
// more than the floor between them, in one connected piece. The normals are tilted by about a
// degree, as a fit on a 0.2 mm scan gives them: a hypothesis tilted through both surfaces holds
// as many points within the 1.5 mm tolerance as either, in stripes, and its fit stays tilted.
// With the fit band of the scan's noise (3 sigma) the floor is found on its own, and the insides,
// found before or after it, are a layer of parts on it.
TEST(Planes, WithAFitBandTheFloorIsFoundApartFromCapInsidesJustAboveIt) {
  Bin bin;
  Rng rng(11);
  auto inDisc = [](float x, float y) {
    for (const float cx : {-62.0f, 0.0f, 62.0f})
      for (const float cy : {-31.0f, 31.0f})
        if ((x - cx) * (x - cx) + (y - cy) * (y - cy) <= 31.0f * 31.0f) return true;
    return false;
  };
  for (float x = -100; x <= 100; x += kSpacing)
    for (float y = -70; y <= 70; y += kSpacing) bin.add(Vec3(x, y, inDisc(x, y) ? 497 : 500), Vec3(0, 0, -1), inDisc(x, y) ? 2 : 0, rng);
  for (Vec3& n : bin.normals)  // about 1 degree (0.0175 rad) off in each direction
    n = Vec3(0.0175f * test::gaussian(rng), 0.0175f * test::gaussian(rng), -1.0f).normalized();
  PlaneParams params;
  params.hole = 60.0f;
  params.fit_band = 0.6f;  // 3 x 0.2 mm
  std::vector<Plane> background;
  const std::vector<char> flat = largePlanes(bin.points, bin.normals, 1.0f / (kSpacing * kSpacing), params, &background);
  const auto [count, removed] = tally(bin, flat);
  EXPECT_GT(count[2], count[0]) << "the insides show more than the floor";
  EXPECT_GE(removed[0], 0.85 * count[0]) << "floor (but pieces between the insides smaller than min_area)";
  EXPECT_EQ(removed[2], 0) << "insides";
  ASSERT_EQ(background.size(), 1u) << "the floor alone";
  EXPECT_NEAR(background[0].normal.z() * background[0].d, 500.0f, 0.2f);
  EXPECT_GT(std::abs(background[0].normal.z()), std::cos(0.2f * float(M_PI) / 180.0f)) << "not tilted";
}
