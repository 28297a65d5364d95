// Bodies of revolution (symmetry.hpp): the axis, orbits, their consistency graph and the axis
// pose, against poses known exactly; and the detector on a simulated bin of caps.
#include <binpose/detector.hpp>
#include <binpose/model_database.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>
#include <binpose/symmetry.hpp>

#include "stage_settings.hpp"
#include "synthetic.hpp"
#include "test_util.hpp"

#include <set>

using namespace binpose;

namespace {

Mesh moved(Mesh mesh, const Pose& pose) {
  for (Vec3& v : mesh.vertices) v = pose * v;
  return mesh;
}

const ModelDatabase& capDatabase() {
  static const ModelDatabase db = [] {
    ModelParams mp;
    mp.num_points = 1500;
    const OrientedModel model = prepareModel(makeCap(), mp);
    return ModelDatabase::build(model, defaultQuantization(model.diameter));
  }();
  return db;
}

const Orbits& capOrbits() {
  static const Orbits orbits = [] {
    const auto axis = findRevolutionAxis(capDatabase().model());
    if (!axis) throw Error("no axis");
    return makeOrbits(capDatabase(), *axis, capDatabase().model().sample_radius);
  }();
  return orbits;
}

float angleDeg(const Vec3& a, const Vec3& b) { return float(test::deg(std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0f, 1.0f)))); }

/// Copies of `count` model points at `pose`, the whole part turned by `turn` about its axis
/// first, each paired with its orbit's first point (another place on the same ring).
struct PosedSample {
  Points scene, normals;
  std::vector<Correspondence> cps;
  std::vector<std::uint32_t> ids;  ///< the model points of cps
};
PosedSample posedSample(const Pose& pose, float turn, std::size_t count, std::uint64_t seed) {
  const Orbits& o = capOrbits();
  const OrientedModel& m = capDatabase().model();
  const Eigen::AngleAxisf spin(turn, o.axis.direction);
  Rng rng(seed);
  PosedSample s;
  std::set<std::uint32_t> used;
  while (s.scene.size() < count) {
    const auto i = static_cast<std::uint32_t>(rng.below(m.points.size()));
    if (!used.insert(i).second) continue;
    s.scene.push_back(pose * (o.axis.point + spin * (m.points[i] - o.axis.point)));
    s.normals.push_back(pose.linear() * (spin * m.normals[i]));
    const std::uint32_t member = o.member[o.of[i]];
    s.cps.push_back({static_cast<std::uint32_t>(s.scene.size() - 1), member});
    s.ids.push_back(member);
  }
  return s;
}

}  // namespace

TEST(Revolution, FindsTheCapsAxisAndNoneForABox) {
  const auto axis = findRevolutionAxis(capDatabase().model());
  ASSERT_TRUE(axis.has_value());
  EXPECT_GT(std::abs(axis->direction.z()), 0.999f);  // makeCap: the axis is z through the origin
  EXPECT_LT(Vec3(axis->point.x(), axis->point.y(), 0).norm(), 0.3f);
  // The same cap turned and moved: the axis turns with it.
  Rng rng(3);
  const Pose pose = test::randomPose(rng, Vec3(10, -20, 30));
  ModelParams mp;
  mp.num_points = 1500;
  const auto turned = findRevolutionAxis(prepareModel(moved(makeCap(), pose), mp));
  ASSERT_TRUE(turned.has_value());
  EXPECT_LT(std::min(angleDeg(turned->direction, pose.linear() * Vec3::UnitZ()),
                     angleDeg(-turned->direction, pose.linear() * Vec3::UnitZ())), 0.5f);
  // No principal axis of a box (or of a box with unequal sides) is one of revolution.
  EXPECT_FALSE(findRevolutionAxis(prepareModel(makeBox({60, 40, 20}, 4), mp)).has_value());
  EXPECT_FALSE(findRevolutionAxis(prepareModel(makeBox({40, 40, 20}, 4), mp)).has_value());
}

TEST(Revolution, ProfileKeepsWhatATurnKeeps) {
  const RevolutionAxis axis{Vec3::Zero(), Vec3::UnitZ()};
  const ProfilePoint p = profileOf(axis, Vec3(3, 4, 5), Vec3(0.6f, 0.8f, 0.0f));  // by hand: r 5, z 5, all radial
  EXPECT_NEAR(p.r, 5.0f, 1e-5f);
  EXPECT_NEAR(p.z, 5.0f, 1e-5f);
  EXPECT_NEAR(p.nr, 1.0f, 1e-5f);
  EXPECT_NEAR(p.nz, 0.0f, 1e-5f);
  const Vec3 n = Vec3(0.6f, 0.0f, 0.8f);  // tilted: radial 0.6, axial 0.8
  const Eigen::AngleAxisf turn(1.1f, Vec3::UnitZ());
  const ProfilePoint a = profileOf(axis, Vec3(2, 0, -1), n), b = profileOf(axis, turn * Vec3(2, 0, -1), turn * n);
  EXPECT_NEAR(a.r, 2.0f, 1e-5f);
  EXPECT_NEAR(a.z, -1.0f, 1e-5f);
  EXPECT_NEAR(a.nr, 0.6f, 1e-5f);
  EXPECT_NEAR(a.nz, 0.8f, 1e-5f);
  EXPECT_NEAR(b.r, a.r, 1e-5f);
  EXPECT_NEAR(b.z, a.z, 1e-5f);
  EXPECT_NEAR(b.nr, a.nr, 1e-5f);
  EXPECT_NEAR(b.nz, a.nz, 1e-5f);
}

TEST(Revolution, OrbitListsHoldTheOrbitsOfTheDatabaseLists) {
  const ModelDatabase& db = capDatabase();
  const Orbits& o = capOrbits();
  EXPECT_GT(o.count, 50u);  // the cap's profile is about 120 mm long, cells of about 2 mm
  EXPECT_LT(o.count, 400u);
  for (std::uint32_t orbit = 0; orbit < o.count; ++orbit) EXPECT_EQ(o.of[o.member[orbit]], orbit);
  std::size_t checked = 0;
  for (std::uint32_t key = 0; key < db.keySpace().size(); key += 7) {
    const auto ids = db.lookup(key);
    std::set<std::uint32_t> expected;
    for (const auto id : ids) expected.insert(o.of[id]);
    const auto got = o.lookup(key);
    ASSERT_EQ(got.size(), expected.size()) << "key " << key;
    EXPECT_TRUE(std::equal(got.begin(), got.end(), expected.begin())) << "key " << key;
    checked += !ids.empty();
  }
  EXPECT_GT(checked, 1000u);
}

// Scene points of a turned, posed cap paired with other points of their rings: every pair of
// them is consistent (some turn explains it), and the largest clique among them and as many
// pairs to wrong orbits is theirs.
TEST(Revolution, ConsistencyGraphLinksTrueOrbitPairsAtAnyTurn) {
  Rng rng(11);
  const Pose pose = test::randomPose(rng, Vec3(0, 0, 500));
  const PosedSample s = posedSample(pose, 0.7f, 20, 5);
  std::vector<Correspondence> cps = s.cps;
  const Orbits& o = capOrbits();
  for (std::uint32_t k = 0; k < 20; ++k) {  // each scene point also paired with an orbit 8+ mm away in the profile
    std::uint32_t wrong;
    do wrong = static_cast<std::uint32_t>(rng.below(o.of.size()));
    while ((o.inPlane(o.of[wrong]) - o.inPlane(o.of[s.ids[k]])).norm() < 8.0f);
    cps.push_back({k, wrong});
  }
  const Graph g = revolutionConsistencyGraph(cps, s.scene, s.normals, o, 1.5f, 15.0f);
  for (int a = 0; a < 20; ++a)
    for (int b = a + 1; b < 20; ++b) EXPECT_TRUE(g.adjacent(a, b)) << a << " " << b;
  const CliqueResult clique = maximumClique(g, 100000);
  ASSERT_EQ(clique.vertices.size(), 20u);
  for (int v = 0; v < 20; ++v) EXPECT_EQ(clique.vertices[v], v);
}

// The pose of 12 noisy oriented points, each paired with another point of its ring: the
// true pose up to a turn about the axis (the turn set by the first point).
TEST(Revolution, AxisPoseRecoversTheTruePoseUpToATurn) {
  const Orbits& o = capOrbits();
  const OrientedModel& m = capDatabase().model();
  Rng rng(21);
  for (int trial = 0; trial < 20; ++trial) {
    const Pose pose = test::randomPose(rng, Vec3(0, 0, 500));
    PosedSample s = posedSample(pose, float(rng.uniform() * 6.28), 12, 100 + trial);
    for (std::size_t i = 0; i < s.scene.size(); ++i) {
      s.scene[i] += 0.1f * Vec3(test::gaussian(rng), test::gaussian(rng), test::gaussian(rng));
      s.normals[i] = (s.normals[i] + 0.03f * Vec3(test::gaussian(rng), test::gaussian(rng), test::gaussian(rng))).normalized();
    }
    const PoseFit fit = solveRevolutionPose(o, s.ids, m.points, s.scene, s.normals);
    ASSERT_TRUE(fit.ok) << trial;
    EXPECT_LT(fit.rms, 1.0f) << trial;
    // The axis and the centroid where the true pose puts them; the first point on its scene point.
    EXPECT_LT(angleDeg(fit.pose.linear() * o.axis.direction, pose.linear() * o.axis.direction), 3.0f) << trial;
    EXPECT_LT((fit.pose * o.axis.point - pose * o.axis.point).norm(), 1.0f) << trial;
    // (its profile is its orbit's mean: up to about a cell, 1.4 mm here, from its own)
    EXPECT_LT((fit.pose * m.points[s.ids[0]] - s.scene[0]).norm(), 2.0f) << trial;
  }
  // Fewer than three points, or mismatched sizes: no pose.
  const PosedSample s = posedSample(Pose::Identity(), 0.0f, 2, 9);
  EXPECT_FALSE(solveRevolutionPose(o, s.ids, m.points, s.scene, s.normals).ok);
}

// A simulated bin of sixteen caps: matched as a body of revolution, the detector finds at
// least three quarters of the caps more than half visible (9 of 12 when written), each pose
// right up to a turn about the axis; matched point to point, fewer (7). One cap seen from its
// mouth came out upside down (score 0.38) and one pose scoring 0.17 was wrong: at most two.
TEST(Revolution, DetectorFindsTheCapsOfABin) {
  const Mesh mesh = makeCap();
  const OrientedModel model = prepareModel(mesh, ModelParams{});
  const ModelDatabase db = ModelDatabase::build(model, defaultQuantization(model.diameter));
  SimulationParams sp;
  sp.seed = 7;
  const SimulatedScene bin = simulateBin(mesh, sp);
  // Right up to a turn: the centroid within 3 mm and the axis within 3 degrees.
  const auto right = [](const Detection& d, const SimulatedInstance& inst) {
    return (d.pose * Vec3(0, 0, 10) - inst.pose * Vec3(0, 0, 10)).norm() < 3.0f &&
           angleDeg(d.pose.linear() * Vec3::UnitZ(), inst.pose.linear() * Vec3::UnitZ()) < 3.0f;
  };
  std::size_t found[2] = {0, 0}, half_visible = 0;
  for (const bool revolution : {false, true}) {
    StageSettings p = stageSettings(scaledToModel(defaultPreset(), model.diameter), model.diameter);
    p.use_revolution = revolution;
    p.use_cyclic_symmetry = false;  // point to point without (a body of revolution has every order n)
    const Detector detector(db, p);
    EXPECT_EQ(detector.orbits() != nullptr, revolution);
    const DetectionResult result = detector.detect(bin.cloud);
    std::size_t wrong = 0;
    for (const Detection& d : result.detections)
      wrong += std::none_of(bin.instances.begin(), bin.instances.end(), [&](const auto& inst) { return right(d, inst); });
    EXPECT_LE(wrong, revolution ? 2u : 0u) << "revolution " << revolution;
    for (const auto& inst : bin.instances) {
      if (inst.visib_fract <= 0.5f) continue;
      half_visible += revolution;
      found[revolution] += std::any_of(result.detections.begin(), result.detections.end(),
                                       [&](const Detection& d) { return right(d, inst); });
    }
  }
  EXPECT_GE(half_visible, 8u);
  EXPECT_GE(4 * found[1], 3 * half_visible);
  EXPECT_LT(found[0], found[1]);
}
