// Parts of n-fold symmetry (cyclic_symmetry.hpp): the symmetry found on IPD obj 8 (17 teeth,
// per its models_info.json) and on no other part, the consistency graph and the pose of
// correspondences whose model points are any of their images, against poses known exactly.
#include <binpose/clique.hpp>
#include <binpose/cyclic_symmetry.hpp>
#include <binpose/io.hpp>
#include <binpose/model.hpp>

#include "test_util.hpp"

#include <random>
#include <span>

#include <tbb/task_arena.h>

using namespace binpose;

namespace {

/// A made-up part of n-fold symmetry (5 unless told) about the z axis through (10, -20, 5): the
/// n images of 40 random oriented points. Members (one image of each) are points 0..39.
struct FiveFold {
  CyclicSymmetry sym{RevolutionAxis{Vec3(10, -20, 5), Vec3::UnitZ()}, 5};
  OrientedModel model;
  explicit FiveFold(std::uint64_t seed, int order = 5) {
    sym.order = order;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    Points base, normals;
    for (int i = 0; i < 40; ++i) {
      base.push_back(sym.axis.point + Vec3(30 * u(rng), 30 * u(rng), 10 * u(rng)));
      normals.push_back(Vec3(u(rng), u(rng), u(rng)).normalized());
    }
    for (int k = 0; k < sym.order; ++k)
      for (int i = 0; i < 40; ++i) {
        model.points.push_back(sym.turn(k) * base[i]);
        model.normals.push_back(sym.turn(k).linear() * normals[i]);
      }
    model.diameter = 90;
    model.sample_radius = 1;
  }
};

Pose somePose() {
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisf(0.7f, Vec3(1, 2, -1).normalized()).toRotationMatrix();
  pose.translation() = Vec3(40, -15, 480);
  return pose;
}

/// The least difference between `pose` and truth * turn(k) over the turns k, as the largest
/// entry of the difference of their 4 x 4 matrices.
float offBySymmetry(const Pose& pose, const Pose& truth, const CyclicSymmetry& sym) {
  float best = INFINITY;
  for (int k = 0; k < sym.order; ++k) {
    const Eigen::Matrix4f d = pose.matrix() - (truth * sym.turn(k)).matrix();
    best = std::min(best, d.cwiseAbs().maxCoeff());
  }
  return best;
}

}  // namespace

TEST(CyclicSymmetry, SeventeenTeethOfIpdObj8AndNoSymmetryOfObj0) {
  REQUIRE_DATA("ipd_parts/models/obj_000008.ply");
  const OrientedModel gear = prepareModel(readMesh(test::dataPath("ipd_parts/models/obj_000008.ply")), ModelParams{});
  const auto sym = findCyclicSymmetry(gear);
  ASSERT_TRUE(sym.has_value());
  EXPECT_EQ(sym->order, 17);  // models_info.json: 16 turns about the model's y axis, and the identity
  EXPECT_GT(std::abs(sym->axis.direction.dot(Vec3::UnitY())), 0.999f);
  // The axis passes through the model's origin (its listed turns move nothing there).
  const Vec3 p = sym->axis.point;
  EXPECT_LT(std::hypot(p.x(), p.z()), 1.0f) << "axis through " << p.transpose();

  const OrientedModel part = prepareModel(readMesh(test::dataPath("ipd_parts/models/obj_000000.ply")), ModelParams{});
  EXPECT_FALSE(findCyclicSymmetry(part).has_value());  // models_info.json lists none
}

TEST(CyclicSymmetry, PoseFromPointsTakenAtAnyOfTheirImages) {
  const FiveFold part(3);
  const Pose truth = somePose();
  std::mt19937 rng(11);
  Points members, scene;
  for (int i = 0; i < 12; ++i) {
    const int k = static_cast<int>(rng() % 5);
    members.push_back(part.model.points[i]);
    scene.push_back(truth * part.sym.turn(k) * part.model.points[i]);
  }
  const PoseFit fit = solveCyclicPose(part.sym, members, scene);
  ASSERT_TRUE(fit.ok);
  EXPECT_LT(fit.rms, 1e-3f);
  EXPECT_LT(offBySymmetry(fit.pose, truth, part.sym), 1e-3f);
  // Taken as they are, the same pairs fit no rigid pose.
  const PoseFit plain = solvePose(members, scene);
  EXPECT_TRUE(!plain.ok || plain.rms > 1.0f) << "rms " << plain.rms;
}

TEST(CyclicSymmetry, RightPairsAreLinkedWhateverTheirImagesAndFormTheLargestClique) {
  const FiveFold part(5);
  const Pose truth = somePose();
  std::mt19937 rng(17);
  Points scene, scene_normals;
  std::vector<Correspondence> cps;
  for (std::uint32_t i = 0; i < 15; ++i) {
    const Pose image = truth * part.sym.turn(static_cast<int>(rng() % 5));
    scene.push_back(image * part.model.points[i]);
    scene_normals.push_back(image.linear() * part.model.normals[i]);
    cps.push_back({i, i});                                          // right, at some image
    cps.push_back({i, static_cast<std::uint32_t>(20 + rng() % 20)});  // a wrong member
  }
  const Graph g = cyclicConsistencyGraph(cps, scene, scene_normals, part.model, part.sym, 0.5f, 10.0f);
  for (int a = 0; a < 30; a += 2)
    for (int b = a + 2; b < 30; b += 2) EXPECT_TRUE(g.adjacent(a, b)) << "right pairs " << a / 2 << ", " << b / 2;
  const CliqueResult clique = maximumClique(g, 1000000);
  ASSERT_EQ(clique.vertices.size(), 15u);
  for (const int v : clique.vertices) EXPECT_EQ(v % 2, 0) << "wrong candidate of point " << v / 2 << " in the clique";
}

namespace {

/// Whether cps[i] and cps[j] are linked by the graph's definition, turn by turn with posed
/// points: 1 (some turn passes every test by `margin`), 0 (every turn fails one by `margin`) or
/// -1 (too close to call in floating point).
int linkedByDefinition(const Correspondence& ci, const Correspondence& cj, const Points& scene, const Points& normals,
                       const OrientedModel& model, const CyclicSymmetry& sym, float e_gmax, float max_angle_deg,
                       float margin) {
  if (ci.scene == cj.scene) return 0;
  const float tol = std::sin(max_angle_deg * float(M_PI) / 180.0f);
  const Vec3 d = scene[cj.scene] - scene[ci.scene];
  const float ds = d.norm();
  const Vec3& ni = normals[ci.scene];
  const Vec3& nj = normals[cj.scene];
  const Vec3& a = model.points[ci.model];
  const Vec3& ui = model.normals[ci.model];
  bool unsure = false;
  for (int k = 0; k < sym.order; ++k) {
    const Pose turn = sym.turn(k);
    const Vec3 b = turn * model.points[cj.model];
    const Vec3 uj = turn.linear() * model.normals[cj.model];
    const float dm = (b - a).norm();
    const float slack = tol * ds + e_gmax;
    // Each test's room: positive when it passes, negative when it fails.
    const float room = std::min({dm - std::max(0.0f, ds - e_gmax), ds + e_gmax - dm,
                                 tol - std::abs(ui.dot(uj) - ni.dot(nj)),
                                 slack - std::abs(ui.dot(b - a) - ni.dot(d)),
                                 slack - std::abs(uj.dot(a - b) + nj.dot(d))});
    if (room >= margin) return 1;
    if (room > -margin) unsure = true;
  }
  return unsure ? -1 : 0;
}

/// Pairs of scene points on a posed part, each at a random one of its images (noisy by 0.3 mm
/// and about 3 degrees), and three candidates each: its member, a random member and a random
/// point at any image.
struct CandidateSet {
  Points scene, normals;
  std::vector<Correspondence> cps;
  CandidateSet(const FiveFold& part, std::uint64_t seed) {
    const Pose truth = somePose();
    std::mt19937 rng(seed);
    std::normal_distribution<float> noise(0.0f, 1.0f);
    const auto points = static_cast<std::uint32_t>(part.model.points.size());
    for (std::uint32_t i = 0; i < 40; ++i) {
      const Pose image = truth * part.sym.turn(static_cast<int>(rng() % part.sym.order));
      scene.push_back(image * part.model.points[i] + 0.3f * Vec3(noise(rng), noise(rng), noise(rng)));
      normals.push_back(
          (image.linear() * part.model.normals[i] + 0.05f * Vec3(noise(rng), noise(rng), noise(rng))).normalized());
      for (const std::uint32_t m : {i, static_cast<std::uint32_t>(rng() % 40), static_cast<std::uint32_t>(rng() % points)})
        cps.push_back({i, m});
    }
  }
};

}  // namespace

TEST(CyclicSymmetry, GraphIsItsDefinitionTestedTurnByTurn) {
  // 36 turns as well as 5: the graph takes the turns 32 at a time.
  for (const int order : {5, 36}) {
    const FiveFold part(order, static_cast<std::uint64_t>(order));
    const CandidateSet set(part, 23);
    const float e_gmax = 1.0f, max_angle = 10.0f;
    const Graph g = cyclicConsistencyGraph(set.cps, set.scene, set.normals, part.model, part.sym, e_gmax, max_angle);
    const int n = static_cast<int>(set.cps.size());
    int linked = 0, unsure = 0, wrong = 0;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        if (i == j) continue;
        const int truth = linkedByDefinition(set.cps[i], set.cps[j], set.scene, set.normals, part.model, part.sym,
                                             e_gmax, max_angle, 1e-3f);
        if (truth < 0) {
          ++unsure;
          continue;
        }
        linked += truth;
        if (g.adjacent(i, j) != (truth == 1)) {
          ++wrong;
          if (wrong <= 5) ADD_FAILURE() << "order " << order << ": pair " << i << ", " << j << " linked " << g.adjacent(i, j);
        }
      }
    EXPECT_EQ(wrong, 0) << "order " << order;
    EXPECT_LT(unsure, n * n / 1000) << "order " << order;
    // Both kinds of pair are there to get wrong: about a third of the candidates are right.
    EXPECT_GT(linked, n * n / 20) << "order " << order;
    EXPECT_LT(linked, n * n / 2) << "order " << order;
  }
}

TEST(CyclicSymmetry, BuffersKeptFromCallToCallGiveAFreshThreadsAnswer) {
  // The graph's row buffers and the pose's are each thread's, kept from one call to the next:
  // graphs of 9, 120, 60 and 120 candidates and fits of 12, 3 and 20 pairs in turn on one
  // thread give what a thread that never ran one gives.
  const FiveFold part(7);
  const CandidateSet set(part, 29);
  tbb::task_arena one(1);
  for (const std::size_t n : {9, 120, 60, 120}) {
    const std::span<const Correspondence> cps(set.cps.data(), n);
    auto graph = [&] { return cyclicConsistencyGraph(cps, set.scene, set.normals, part.model, part.sym, 1.0f, 10.0f); };
    Graph kept(0);
    one.execute([&] { kept = graph(); });
    const Graph first = test::onFreshThread(graph);
    ASSERT_EQ(kept.size(), first.size());
    for (int v = 0; v < kept.size(); ++v)
      for (int w = 0; w < kept.words(); ++w) ASSERT_EQ(kept.row(v)[w], first.row(v)[w]) << n << " candidates, row " << v;
  }
  const Pose truth = somePose();
  std::mt19937 rng(31);
  for (const int m : {12, 3, 20}) {
    Points members, scene;
    for (int i = 0; i < m; ++i) {
      members.push_back(part.model.points[i]);
      scene.push_back(truth * part.sym.turn(static_cast<int>(rng() % 5)) * part.model.points[i]);
    }
    PoseFit kept;
    one.execute([&] { kept = solveCyclicPose(part.sym, members, scene); });
    const PoseFit first = test::onFreshThread([&] { return solveCyclicPose(part.sym, members, scene); });
    ASSERT_TRUE(kept.ok) << m << " pairs";
    EXPECT_EQ(kept.pose.matrix(), first.pose.matrix()) << m << " pairs";
    EXPECT_LT(offBySymmetry(kept.pose, truth, part.sym), 1e-3f) << m << " pairs";
  }
}
