// Fourth-spread selection (4.4), maximum clique (4.5) and pose (4.6) against known answers.
#include <binpose/clique.hpp>
#include <binpose/features.hpp>
#include <binpose/geometry.hpp>
#include <binpose/pose.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/shapes.hpp>
#include <binpose/voting.hpp>

#include "synthetic.hpp"

#include "test_util.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <numeric>

#include <tbb/task_arena.h>

using namespace binpose;

// ---- fourth spread ----------------------------------------------------------------------------

namespace {
Fourths fourthsOf(std::vector<std::uint32_t> values) {
  std::vector<std::uint32_t> h(*std::max_element(values.begin(), values.end()) + 1, 0);
  for (auto v : values) ++h[v];
  return fourthsOfHistogram(h);
}
}  // namespace

TEST(FourthSpread, TextbookValues) {
  // Even n = 8: halves {1,2,3,4} and {5,6,7,8} -> x_l = 2.5, x_u = 6.5.
  Fourths f = fourthsOf({8, 1, 7, 2, 6, 3, 5, 4});
  EXPECT_DOUBLE_EQ(f.lower, 2.5);
  EXPECT_DOUBLE_EQ(f.upper, 6.5);
  EXPECT_DOUBLE_EQ(f.spread(), 4.0);
  // Odd n = 7: the median 4 in both halves: {1,2,3,4} and {4,5,6,7} -> 2.5 and 5.5.
  f = fourthsOf({1, 2, 3, 4, 5, 6, 7});
  EXPECT_DOUBLE_EQ(f.lower, 2.5);
  EXPECT_DOUBLE_EQ(f.upper, 5.5);
  // n = 5: {1,2,3} and {3,4,9} -> 2 and 4.
  f = fourthsOf({9, 1, 3, 2, 4});
  EXPECT_DOUBLE_EQ(f.lower, 2.0);
  EXPECT_DOUBLE_EQ(f.upper, 4.0);
  EXPECT_THROW(fourthsOfHistogram(std::vector<std::uint32_t>{0, 0}), Error);
}

TEST(FourthSpread, SelectsOnlyExtremeMaxima) {
  // Bulk 1..4 (x_l = 1.5, x_u = 3.5 with 12 values), spread 2 -> threshold 3.5 + 6 = 9.5.
  std::vector<std::uint32_t> acc{1, 2, 3, 4, 1, 2, 3, 4, 1, 2, 3, 4};
  EXPECT_TRUE(selectCandidates(acc).empty()) << "no outlier, no candidate";
  acc.push_back(9);  // 9 < 9.5: still not an extreme outlier
  EXPECT_TRUE(selectCandidates(acc).empty());
  acc.back() = 12;  // one clear outlier
  EXPECT_EQ(selectCandidates(acc), std::vector<std::size_t>{12});
  acc.push_back(11);  // two outliers: only the maximum is kept (eq. 12)
  EXPECT_EQ(selectCandidates(acc), std::vector<std::size_t>{12});
  acc.push_back(12);  // tied maxima are all kept
  EXPECT_EQ(selectCandidates(acc), (std::vector<std::size_t>{12, 14}));
  EXPECT_TRUE(selectCandidates(std::vector<std::uint32_t>{5, 5, 5, 5}).empty()) << "flat: indiscriminant";
  EXPECT_TRUE(selectCandidates(std::vector<std::uint32_t>{}).empty());
}

namespace {
/// x_u + 3 xi_s (eq. 11) of an accumulator's non-zero counts, from their whole histogram.
double limitOfVoted(std::span<const std::uint16_t> votes) {
  std::vector<std::uint32_t> voted;
  for (const auto v : votes)
    if (v > 0) voted.push_back(v);
  const Fourths f = fourthsOf(voted);
  return f.upper + 3.0 * f.spread();
}
}  // namespace

TEST(FourthSpread, CutOfAnAccumulatorIsTheFullHistograms) {
  // upperOutlierCut counts the histogram only as far as the fourths need (with AVX2, on the votes
  // as bytes, eight values a pass): its top and limit must be those of every non-zero count's.
  // Accumulators of 128 multiples (the fast path; 40064 read out in several runs) and not, with
  // zeros, gaps between the values (where stopping a bin early would show), ties, tops at 255
  // and 256, and every vote equal.
  Rng rng(41);
  std::vector<std::uint8_t> bytes;
  std::vector<std::uint32_t> histogram;
  int checked = 0;
  for (const std::size_t size : {32u, 128u, 4000u, 4096u, 4095u, 40064u})
    for (const int top : {1, 2, 7, 8, 9, 30, 120, 255, 256, 3000})
      for (const double zeros : {0.0, 0.3, 0.95})
        for (const int step : {1, 3, 17}) {  // votes only on multiples of step (gaps between)
          std::vector<std::uint16_t> votes(size);
          for (auto& v : votes) {
            // Mostly low counts, a few high: the scans' accumulators have this shape.
            const double u = rng.uniform();
            const int value = static_cast<int>(top * u * u * u);
            v = static_cast<std::uint16_t>(rng.uniform() < zeros ? 0 : std::max(1, value - value % step));
          }
          votes[rng.below(size)] = static_cast<std::uint16_t>(top);
          const VoteCut cut = upperOutlierCut(votes, bytes, histogram);
          ASSERT_EQ(cut.top, top);
          EXPECT_EQ(cut.limit, limitOfVoted(votes)) << size << " " << top << " " << zeros << " " << step;
          ++checked;
        }
  EXPECT_EQ(checked, 540);
  std::vector<std::uint16_t> high(128);  // most votes at 255 and 256: a byte cannot hold them
  for (std::size_t i = 0; i < high.size(); ++i) high[i] = static_cast<std::uint16_t>(i % 3 == 0 ? 255 : 256);
  high[5] = 1;
  EXPECT_EQ(upperOutlierCut(high, bytes, histogram).limit, limitOfVoted(high));
  std::vector<std::uint16_t> none(64, 0);
  EXPECT_EQ(upperOutlierCut(none, bytes, histogram).top, 0) << "no vote";
  std::vector<std::uint16_t> equal(64, 5);
  const VoteCut flat = upperOutlierCut(equal, bytes, histogram);
  EXPECT_EQ(flat.top, 5);
  EXPECT_EQ(flat.limit, 5.0) << "every vote equal: no spread, no outlier";
}

// ---- maximum clique ---------------------------------------------------------------------------

namespace {
/// Reference: plain Bron-Kerbosch (no pivot, no bounds) enumerates every maximal clique.
void bronKerbosch(const Graph& g, std::vector<int> R, std::vector<int> P, std::vector<int> X, int& best) {
  if (P.empty() && X.empty()) best = std::max(best, static_cast<int>(R.size()));
  while (!P.empty()) {
    const int v = P.back();
    std::vector<int> P2, X2;
    for (int u : P) if (g.adjacent(u, v)) P2.push_back(u);
    for (int u : X) if (g.adjacent(u, v)) X2.push_back(u);
    R.push_back(v);
    bronKerbosch(g, R, P2, X2, best);
    R.pop_back();
    P.pop_back();
    X.push_back(v);
  }
}

/// G(n, density): each edge present with that probability.
Graph randomGraph(int n, double density, Rng& rng) {
  Graph g(n);
  for (int a = 0; a < n; ++a)
    for (int b = a + 1; b < n; ++b)
      if (rng.uniform() < density) g.addEdge(a, b);
  return g;
}

int bruteForceClique(const Graph& g) {
  std::vector<int> all(static_cast<std::size_t>(g.size()));
  std::iota(all.begin(), all.end(), 0);
  int best = 0;
  bronKerbosch(g, {}, all, {}, best);
  return best;
}
}  // namespace

TEST(Clique, MatchesBruteForceOnRandomGraphs) {
  Rng rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 4 + static_cast<int>(rng.below(27));  // 4 to 30 vertices
    const double density = 0.2 + 0.7 * rng.uniform();
    Graph g = randomGraph(n, density, rng);
    const CliqueResult r = maximumClique(g, 10000000);
    ASSERT_TRUE(r.exact);
    EXPECT_EQ(static_cast<int>(r.vertices.size()), bruteForceClique(g)) << "trial " << trial;
    for (std::size_t i = 0; i < r.vertices.size(); ++i)
      for (std::size_t j = i + 1; j < r.vertices.size(); ++j) ASSERT_TRUE(g.adjacent(r.vertices[i], r.vertices[j]));
  }
}

TEST(Clique, BitBlockTransposeOnRegistersAndScalarMatchesItsDefinition) {
  Rng rng(12);
  for (int trial = 0; trial < 50; ++trial) {
    std::array<std::uint64_t, 64> a;
    for (auto& w : a) w = trial % 5 == 0 ? rng.next() & rng.next() & rng.next() : rng.next();  // sparse blocks too
    for (const bool simd : {true, false}) {
      std::array<std::uint64_t, 64> t = a;
      transposeBits64(t, simd);
      for (int r = 0; r < 64; ++r)
        for (int c = 0; c < 64; ++c)
          ASSERT_EQ((t[c] >> r) & 1u, (a[r] >> c) & 1u) << "trial " << trial << " simd " << simd << " row " << r << " column " << c;
    }
  }
}

TEST(Clique, ThirtyVerticesAndAPlantedClique) {
  Rng rng(6);
  for (int trial = 0; trial < 8; ++trial) {
    const int n = 30;
    Graph g = randomGraph(n, 0.5, rng);
    // Plant a 12-clique, far above what a G(30, 0.5) graph holds (about 7): found exactly.
    std::vector<int> planted;
    for (int v = 0; v < n; ++v)
      if (rng.uniform() < 0.4 && planted.size() < 12) planted.push_back(v);
    for (int v = 0; v < n && planted.size() < 12; ++v)
      if (std::find(planted.begin(), planted.end(), v) == planted.end()) planted.push_back(v);
    std::sort(planted.begin(), planted.end());
    for (std::size_t i = 0; i < planted.size(); ++i)
      for (std::size_t j = i + 1; j < planted.size(); ++j) g.addEdge(planted[i], planted[j]);
    const CliqueResult r = maximumClique(g);
    EXPECT_TRUE(r.exact);
    EXPECT_EQ(r.vertices, planted);
  }
}

TEST(Clique, IsolatedVerticesLeaveTheNextLargestClique) {
  // Two planted cliques on 90 vertices (random edges at 0.3): isolating the larger one's
  // vertices leaves the smaller as the maximum, and no edge of an isolated vertex remains.
  Rng rng(8);
  const int n = 90;
  Graph g = randomGraph(n, 0.3, rng);
  std::vector<int> large, small;
  for (int v = 0; v < 14; ++v) large.push_back(5 * v + 2);   // 2, 7, ..., 67
  for (int v = 0; v < 10; ++v) small.push_back(5 * v + 4);   // 4, 9, ..., 49
  for (const auto* c : {&large, &small})
    for (std::size_t i = 0; i < c->size(); ++i)
      for (std::size_t j = i + 1; j < c->size(); ++j) g.addEdge((*c)[i], (*c)[j]);
  ASSERT_EQ(maximumClique(g).vertices, large);
  g.isolate(large);
  for (const int v : large) {
    EXPECT_EQ(g.degree(v), 0) << "vertex " << v;
    for (int u = 0; u < n; ++u) EXPECT_FALSE(g.adjacent(u, v)) << u << "-" << v;
  }
  EXPECT_EQ(maximumClique(g).vertices, small);
}

TEST(Clique, ConsistencyGraphFollowsEquations13To16) {
  // A rigid copy of 60 model points (all consistent) plus 90 random pairs, over three bit words.
  Rng rng(12);
  Points model, scene;
  for (int i = 0; i < 100; ++i) model.emplace_back(Vec3(rng.uniform(), rng.uniform(), rng.uniform()) * 60.0f);
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisf(0.7f, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  pose.translation() = Vec3(5, -20, 300);
  std::vector<Correspondence> cps;
  for (std::uint32_t i = 0; i < 150; ++i) {
    const auto m = static_cast<std::uint32_t>(i < 60 ? i : rng.below(100));
    scene.push_back(i < 60 ? Vec3(pose * model[m]) : Vec3(pose * Vec3(Vec3(rng.uniform(), rng.uniform(), rng.uniform()) * 60.0f)));
    cps.push_back({i, m});
  }
  const float e_gmax = 1.5f;
  const Graph g = consistencyGraph(cps, scene, model, e_gmax);
  int edges = 0;
  for (int a = 0; a < 150; ++a) {
    EXPECT_FALSE(g.adjacent(a, a));
    for (int b = 0; b < 150; ++b) {
      if (a == b) continue;
      const float dm = (model[cps[a].model] - model[cps[b].model]).norm();
      const float ds = (scene[cps[a].scene] - scene[cps[b].scene]).norm();
      if (std::abs(std::abs(dm - ds) - e_gmax) < 1e-4f) continue;  // on the limit: either answer, by rounding
      ASSERT_EQ(g.adjacent(a, b), std::abs(dm - ds) < e_gmax) << a << " " << b;
      ASSERT_EQ(g.adjacent(a, b), g.adjacent(b, a));
      edges += g.adjacent(a, b);
    }
  }
  EXPECT_GT(edges, 60 * 59);  // the rigid copy is one clique
  EXPECT_EQ(maximumClique(g).vertices.size(), 60u);
}

TEST(Clique, ConsistencyGraphOfCandidateRunsFollowsEquations13To16) {
  // The default preset's layout: each scene point's candidates side by side (runs of 1-12 pairs of
  // one scene point, across word boundaries), the first model point of each run the true one.
  Rng rng(31);
  Points model, scene;
  for (int i = 0; i < 300; ++i) model.emplace_back(Vec3(rng.uniform(), rng.uniform(), rng.uniform()) * 60.0f);
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisf(-1.1f, Vec3(2, -1, 1).normalized()).toRotationMatrix();
  pose.translation() = Vec3(-40, 12, 450);
  std::vector<Correspondence> cps;
  for (std::uint32_t s = 0; s < 60; ++s) {
    const auto truth = static_cast<std::uint32_t>(rng.below(300));
    scene.push_back(pose * model[truth]);
    const std::size_t run = 1 + rng.below(12);
    for (std::size_t k = 0; k < run; ++k) cps.push_back({s, k == 0 ? truth : static_cast<std::uint32_t>(rng.below(300))});
  }
  const float e_gmax = 1.5f;
  const Graph g = consistencyGraph(cps, scene, model, e_gmax);
  ASSERT_GT(g.words(), 3);
  for (int a = 0; a < g.size(); ++a)
    for (int b = 0; b < g.size(); ++b) {
      const float dm = (model[cps[a].model] - model[cps[b].model]).norm();
      const float ds = (scene[cps[a].scene] - scene[cps[b].scene]).norm();
      if (a == b || std::abs(std::abs(dm - ds) - e_gmax) < 1e-4f) continue;
      ASSERT_EQ(g.adjacent(a, b), std::abs(dm - ds) < e_gmax) << a << " " << b;
    }
}

TEST(Clique, ConsistencyGraphTestsTheAngleBetweenNormals) {
  // Runs of candidates as in the default preset, each scene point's first candidate its true
  // model point with its normal turned by the pose (plus up to 10 degrees of noise); the others
  // random model points with random normals. With the test of normals, a pair is linked exactly
  // when its distances agree (eq. 13-16) and its normals' angles differ by at most the tolerance.
  Rng rng(47);
  const auto unit = [&] { return Vec3(rng.uniform() - 0.5f, rng.uniform() - 0.5f, rng.uniform() - 0.5f).normalized(); };
  Points model, model_normals, scene, scene_normals;
  for (int i = 0; i < 200; ++i) {
    model.emplace_back(Vec3(rng.uniform(), rng.uniform(), rng.uniform()) * 60.0f);
    model_normals.push_back(unit());
  }
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisf(0.9f, Vec3(1, -2, 2).normalized()).toRotationMatrix();
  pose.translation() = Vec3(10, 30, 500);
  std::vector<Correspondence> cps;
  for (std::uint32_t s = 0; s < 50; ++s) {
    const auto truth = static_cast<std::uint32_t>(rng.below(200));
    scene.push_back(pose * model[truth]);
    const Eigen::AngleAxisf noise(0.1745f * rng.uniform(), unit());
    scene_normals.push_back(noise * (pose.linear() * model_normals[truth]));
    const std::size_t run = 1 + rng.below(8);
    for (std::size_t k = 0; k < run; ++k) cps.push_back({s, k == 0 ? truth : static_cast<std::uint32_t>(rng.below(200))});
  }
  const float e_gmax = 1.5f, tolerance = 25.0f;
  const Graph plain = consistencyGraph(cps, scene, model, e_gmax);
  const Graph g = consistencyGraph(cps, scene, model, e_gmax, nullptr, {&scene_normals, &model_normals, tolerance});
  const auto angle = [](const Vec3& a, const Vec3& b) { return std::acos(std::clamp(a.dot(b), -1.0f, 1.0f)) * 57.29578f; };
  int dropped = 0;
  for (int a = 0; a < g.size(); ++a)
    for (int b = 0; b < g.size(); ++b) {
      if (a == b) continue;
      const float da = std::abs(angle(scene_normals[cps[a].scene], scene_normals[cps[b].scene]) -
                                angle(model_normals[cps[a].model], model_normals[cps[b].model]));
      if (std::abs(da - tolerance) < 0.01f) continue;  // on the limit: either answer, by rounding
      ASSERT_EQ(g.adjacent(a, b), plain.adjacent(a, b) && da <= tolerance) << a << " " << b << " " << da;
      dropped += plain.adjacent(a, b) && !g.adjacent(a, b);
    }
  EXPECT_GT(dropped, 0);
  // The true pairs (noise of at most 10 degrees per normal) are all kept: one clique of 50.
  EXPECT_EQ(maximumClique(g).vertices.size(), 50u);
}

TEST(Clique, CorePruningProvesAPlantedCliqueAmongManyVertices) {
  // 40 rigidly consistent pairs among 1000 sparse random ones: the greedy clique finds them,
  // the 40-core holds nothing else, and the search proves them largest in a handful of nodes.
  Rng rng(9);
  const int n = 1000;
  Graph g = randomGraph(n, 0.02, rng);
  std::vector<int> planted;
  for (int v = 7; v < n && planted.size() < 40; v += 23) planted.push_back(v);
  for (std::size_t i = 0; i < planted.size(); ++i)
    for (std::size_t j = i + 1; j < planted.size(); ++j) g.addEdge(planted[i], planted[j]);
  const CliqueResult r = maximumClique(g, 20);
  EXPECT_TRUE(r.exact);
  EXPECT_LE(r.nodes, 20u);
  EXPECT_EQ(r.vertices, planted);
}

TEST(Clique, WorkBoundStopsEarly) {
  Rng rng(8);
  const int n = 200;
  Graph g = randomGraph(n, 0.9, rng);
  const CliqueResult r = maximumClique(g, 50);
  EXPECT_FALSE(r.exact);
  EXPECT_LE(r.nodes, 51u);
  for (std::size_t i = 0; i < r.vertices.size(); ++i)
    for (std::size_t j = i + 1; j < r.vertices.size(); ++j) ASSERT_TRUE(g.adjacent(r.vertices[i], r.vertices[j]));
  EXPECT_TRUE(maximumClique(Graph(0)).vertices.empty());
}

TEST(Clique, BuffersKeptFromCallToCallGiveAFreshThreadsAnswer) {
  // Graphs of one to four words a row, one after the other on one thread, larger and smaller
  // than the one before: each answer is the one a thread with no buffers yet gives, and holds
  // its planted clique's size at least.
  Rng rng(13);
  tbb::task_arena one(1);
  for (const int n : {150, 12, 90, 220, 7, 64, 65, 130, 3}) {
    Graph g = randomGraph(n, 0.25, rng);
    std::vector<int> planted;
    for (int v = 1; v < n && planted.size() < 9; v += 3) planted.push_back(v);
    for (std::size_t i = 0; i < planted.size(); ++i)
      for (std::size_t j = i + 1; j < planted.size(); ++j) g.addEdge(planted[i], planted[j]);
    CliqueResult kept;
    one.execute([&] { kept = maximumClique(g); });
    const CliqueResult fresh = test::onFreshThread([&] { return maximumClique(g); });
    EXPECT_EQ(kept.vertices, fresh.vertices) << n << " vertices";
    EXPECT_EQ(kept.nodes, fresh.nodes) << n << " vertices";
    EXPECT_GE(kept.vertices.size(), planted.size()) << n << " vertices";
    for (std::size_t i = 0; i < kept.vertices.size(); ++i)
      for (std::size_t j = i + 1; j < kept.vertices.size(); ++j) ASSERT_TRUE(g.adjacent(kept.vertices[i], kept.vertices[j]));
  }
}

TEST(Clique, ResetLeavesNoEdgeAtAnySize) {
  Rng rng(14);
  Graph g = randomGraph(130, 0.5, rng);
  for (const int n : {70, 200, 1}) {
    g.reset(n);
    EXPECT_EQ(g.size(), n);
    EXPECT_EQ(g.words(), (n + 63) / 64);
    for (int v = 0; v < n; ++v) EXPECT_EQ(g.degree(v), 0) << "vertex " << v << " of " << n;
    if (n > 1) {
      g.addEdge(0, n - 1);
      EXPECT_TRUE(g.adjacent(n - 1, 0));
    }
  }
}

// ---- pose -------------------------------------------------------------------------------------

TEST(Pose, BuffersKeptFromCallToCallGiveAFreshThreadsAnswer) {
  // Sets of 40, 3, 25 and 4 pairs in turn on one thread: the same fits, bit for bit, as on a
  // thread that never solved one.
  Rng rng(15);
  for (const int m : {40, 3, 25, 4}) {
    Pose truth = Pose::Identity();
    truth.linear() = Eigen::AngleAxisf(0.3f * float(m), Vec3(1, -2, 0.5f).normalized()).toRotationMatrix();
    truth.translation() = Vec3(10, 20, 300);
    Points model, scene;
    for (int i = 0; i < m; ++i) {
      model.emplace_back(float(rng.uniform() * 40), float(rng.uniform() * 30), float(rng.uniform() * 20));
      scene.push_back(truth * model.back() + Vec3(float(rng.uniform()), float(rng.uniform()), float(rng.uniform())) * 0.2f);
    }
    const PoseFit kept = solvePose(model, scene);
    const PoseFit fresh = test::onFreshThread([&] { return solvePose(model, scene); });
    ASSERT_TRUE(kept.ok);
    EXPECT_EQ(kept.pose.matrix(), fresh.pose.matrix()) << m << " pairs";
    EXPECT_EQ(kept.rms, fresh.rms) << m << " pairs";
    EXPECT_LT((kept.pose.translation() - truth.translation()).norm(), 1.0f) << m << " pairs";
  }
}

TEST(Pose, RecoversRandomRigidTransformsUnderNoise) {
  Rng rng(9);
  auto gauss = [&] {  // Box-Muller
    return float(std::sqrt(-2 * std::log(1 - rng.uniform())) * std::cos(2 * M_PI * rng.uniform()));
  };
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Quaternionf q = Eigen::Quaternionf(gauss(), gauss(), gauss(), gauss()).normalized();
    Pose truth = Pose::Identity();
    truth.linear() = q.toRotationMatrix();
    truth.translation() = Vec3(gauss(), gauss(), gauss()) * 200;
    Points model, scene;
    for (int i = 0; i < 40; ++i) {
      model.push_back(Vec3(gauss(), gauss(), gauss()) * 20);
      scene.push_back(truth * model.back() + Vec3(gauss(), gauss(), gauss()) * 0.1f);
    }
    const PoseFit fit = solvePose(model, scene);
    ASSERT_TRUE(fit.ok);
    const float angle = Eigen::AngleAxisf(fit.pose.linear().transpose() * truth.linear()).angle();
    EXPECT_LT(test::deg(angle), 0.5);
    EXPECT_LT((fit.pose.translation() - truth.translation()).norm(), 0.5f);
    EXPECT_NEAR(fit.rms, 0.1 * std::sqrt(3.0), 0.06);
    EXPECT_NEAR(fit.pose.linear().determinant(), 1.0f, 1e-4f);
  }
}

TEST(Pose, RefusesMirrorImageAndDegenerateSets) {
  Rng rng(10);
  Points model, mirrored;
  for (int i = 0; i < 30; ++i) {
    model.emplace_back(float(rng.uniform() * 40), float(rng.uniform() * 30), float(rng.uniform() * 20));
    mirrored.emplace_back(-model.back().x(), model.back().y(), model.back().z() + 100);
  }
  EXPECT_FALSE(solvePose(model, mirrored).ok) << "a reflection is never returned as a pose";
  EXPECT_FALSE(solvePose({model[0], model[1]}, {model[0], model[1]}).ok);
  const Points line{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0}};
  EXPECT_FALSE(solvePose(line, line).ok);
  // A planar set is fine: its mirror ambiguity is resolved to the proper rotation.
  Points plane, plane_scene;
  for (int i = 0; i < 20; ++i) {
    plane.emplace_back(float(rng.uniform() * 40), float(rng.uniform() * 40), 0.0f);
    plane_scene.push_back(plane.back() + Vec3(5, 6, 7));
  }
  const PoseFit fit = solvePose(plane, plane_scene);
  ASSERT_TRUE(fit.ok);
  EXPECT_LT(fit.rms, 1e-3f);
  EXPECT_TRUE(fit.pose.linear().isIdentity(1e-4f));
}

// ---- voting (4.3-4.4) -------------------------------------------------------------------------

namespace {
/// An L-shaped part of two boxes (no symmetry): every surface point has one true model point.
const ModelDatabase& lDatabase() {
  static const ModelDatabase db = [] {
    Mesh a = makeBox(Vec3(60, 20, 15), 4), b = makeBox(Vec3(20, 40, 15), 4);
    for (Vec3& v : b.vertices) v += Vec3(20, 30, 0);
    const auto offset = static_cast<int>(a.vertices.size());
    a.vertices.insert(a.vertices.end(), b.vertices.begin(), b.vertices.end());
    for (const auto& f : b.faces) a.faces.push_back(f + Eigen::Vector3i::Constant(offset));
    ModelParams mp;
    mp.num_points = 1500;
    const OrientedModel model = prepareModel(a, mp);
    return ModelDatabase::build(model, defaultQuantization(model.diameter));
  }();
  return db;
}

/// Every 3rd model point, moved by `pose`: scene point i is model point 3 i.
void movedModel(const Pose& pose, Points& points, Points& normals) {
  const OrientedModel& m = lDatabase().model();
  for (std::size_t i = 0; i < m.points.size(); i += 3) {
    points.push_back(pose * m.points[i]);
    normals.push_back(pose.linear() * m.normals[i]);
  }
}

/// The part moved by a random pose (from `seed`) to 400 mm ahead, all its points one group.
struct WholePart {
  Points points, normals;
  std::vector<std::uint32_t> group;
};
WholePart wholePart(std::uint64_t seed) {
  WholePart part;
  Rng rng(seed);
  movedModel(test::randomPose(rng, Vec3(0, 0, 400)), part.points, part.normals);
  part.group.resize(part.points.size());
  std::iota(part.group.begin(), part.group.end(), 0u);
  return part;
}

/// Point k's accumulator (eq. 9) counted here, one feature at a time from the table's lists.
std::vector<std::uint32_t> countedVotes(const ModelDatabase& db, const WholePart& part, std::uint32_t k) {
  std::vector<std::uint32_t> counts(db.model().points.size(), 0);
  for (const std::uint32_t o : part.group) {
    PairFeature f;
    if (o == k || !computeFeature(part.points[k], part.normals[k], part.points[o], part.normals[o], f)) continue;
    for (const auto m : db.lookup(db.keySpace().key(f))) ++counts[m];
  }
  return counts;
}
}  // namespace

TEST(Voting, ParallelVoterGivesTheSequentialPairs) {
  const auto [points, normals, group] = wholePart(3);
  std::vector<Correspondence> sequential, parallel;
  Voter(lDatabase(), 2).vote(points, normals, group, sequential);
  ParallelVoter(lDatabase(), 2).vote(points, normals, group, parallel);
  ASSERT_GT(sequential.size(), group.size() / 2);
  EXPECT_EQ(sequential, parallel);
}

TEST(Voting, LongListsHeldAsBitsetsHoldTheSamePoints) {
  const ModelDatabase& db = lDatabase();
  std::size_t dense = 0;
  for (std::uint32_t key = 0; key < db.keySpace().size(); ++key) {
    const auto ids = db.lookup(key);
    const auto bits = db.denseBits(key);
    ASSERT_EQ(bits.empty(), ids.size() < db.denseListSize()) << key;
    if (bits.empty()) continue;
    ++dense;
    std::vector<std::uint32_t> from_bits;
    for (std::uint32_t m = 0; m < 64 * bits.size(); ++m)
      if ((bits[m / 64] >> (m % 64)) & 1) from_bits.push_back(m);
    ASSERT_EQ(from_bits, std::vector<std::uint32_t>(ids.begin(), ids.end())) << key;
  }
  EXPECT_GT(dense, 10u);  // the flat faces' features: lists of a 32nd of the points and more
}

TEST(Voting, BitsetCountingGivesTheSameCandidates) {
  // The whole part as one group (500 partners: a point has up to about 1600 long lists, added
  // 255 at a time into 8 bit planes; equal keys add their count at once), with the default
  // preset's candidate rule.
  const auto [points, normals, group] = wholePart(21);
  Voter by_bits(lDatabase(), 12, 2.7f), by_points(lDatabase(), 12, 2.7f);
  by_points.useBitsets(false);
  if (!by_bits.usesBitsets()) GTEST_SKIP() << "no AVX2 on this CPU: every list is counted point by point";
  std::vector<Correspondence> a, b;
  by_bits.vote(points, normals, group, a);
  by_points.vote(points, normals, group, b);
  ASSERT_GT(a.size(), group.size());
  EXPECT_EQ(a, b);
}

TEST(Voting, VoterSelectsTheUpperOutliersOfItsCounts) {
  // Each point's accumulator counted here, one feature at a time from the table's lists (eq. 9),
  // and its candidates chosen by selectCandidates (eq. 10-12): the Voter's (equal keys grouped, bitsets,
  // vector scans of the accumulator) must be the same. Every point voting with the whole part
  // gives tops over 255 (16-bit counters); with every 9th point as partner, lists adding under
  // 255 votes, as the scans' local votes (counted in bytes, the histogram only as far as the
  // fourths need).
  for (const std::uint32_t stride : {1u, 9u}) {
    WholePart part = wholePart(31);
    std::erase_if(part.group, [&](std::uint32_t i) { return i % stride != 0; });
    const auto& [points, normals, group] = part;
    const ModelDatabase& db = lDatabase();
    for (const int keep : {1, 12}) {
      SCOPED_TRACE(testing::Message() << "partners every " << stride << ", keep " << keep);
      Voter voter(db, keep);
      int with_candidates = 0;
      for (std::uint32_t k = 0; k < points.size(); k += 5) {
        const std::vector<std::uint32_t> counts = countedVotes(db, part, k);
        std::vector<std::uint32_t> voted, values;  // A_k: the model points with a vote, and their votes
        for (std::uint32_t m = 0; m < counts.size(); ++m)
          if (counts[m] > 0) {
            voted.push_back(m);
            values.push_back(counts[m]);
          }
        std::vector<std::size_t> expected = selectCandidates(values, keep);
        for (std::size_t& e : expected) e = voted[e];
        if (keep > 1) {  // selectCandidates gives them best first; with keep 1, the ties in index order
          ASSERT_TRUE(std::is_sorted(expected.begin(), expected.end(),
                                     [&](std::size_t a, std::size_t b) { return counts[a] > counts[b]; }));
        }
        std::vector<Correspondence> got;
        voter.votePoint(points, normals, k, group, got);
        ASSERT_EQ(got.size(), expected.size()) << k;
        for (std::size_t c = 0; c < got.size(); ++c) {
          EXPECT_EQ(got[c].scene, k);
          EXPECT_EQ(got[c].model, expected[c]) << k;
        }
        with_candidates += !got.empty();
      }
      EXPECT_GT(with_candidates, 20) << keep;
    }
  }
}

TEST(Voting, APointWithoutAnUpperOutlierKeepsItsMostVotedMildOnes) {
  // Johnson's fourths of each point's non-zero counts, computed here: a point whose top count is
  // no upper outlier (eq. 11) has no candidate under eq. 11 alone, and with MildOutliers{2, 4}
  // its (at most) 4 most voted above x_u + 2 xi_s; a point with an upper outlier keeps eq. 11's.
  // The normals tilted by about 6 degrees, as a noisy scan's, spread the votes.
  WholePart part = wholePart(17);
  Rng rng(5);
  for (Vec3& n : part.normals) n = (n + 0.1f * Vec3(rng.gaussian(), rng.gaussian(), rng.gaussian())).normalized();
  const auto& [points, normals, group] = part;
  const ModelDatabase& db = lDatabase();
  Voter upper(db, 12), mild(db, 12, 0.0f, nullptr, MildOutliers{2.0f, 4});
  int without_outlier = 0, with_mild = 0;
  for (std::uint32_t k = 0; k < points.size(); k += 3) {
    const std::vector<std::uint32_t> counts = countedVotes(db, part, k);
    std::vector<std::uint32_t> values;
    for (const std::uint32_t c : counts)
      if (c > 0) values.push_back(c);
    std::sort(values.begin(), values.end());
    const std::size_t n = values.size(), half = (n + 1) / 2;
    const auto median = [&](std::size_t from, std::size_t count) {
      return count % 2 ? double(values[from + count / 2]) : 0.5 * (values[from + count / 2 - 1] + values[from + count / 2]);
    };
    const double lower = median(0, half), higher = median(n - half, half), spread = higher - lower;
    std::vector<Correspondence> by_upper, by_mild;
    upper.votePoint(points, normals, k, group, by_upper);
    mild.votePoint(points, normals, k, group, by_mild);
    if (values.back() > higher + 3 * spread) {
      EXPECT_EQ(by_mild, by_upper) << k;
      continue;
    }
    ++without_outlier;
    EXPECT_TRUE(by_upper.empty()) << k;
    const double limit = higher + 2 * spread;
    const auto above = static_cast<std::size_t>(std::count_if(values.begin(), values.end(), [&](std::uint32_t v) { return v > limit; }));
    ASSERT_EQ(by_mild.size(), std::min<std::size_t>(4, above)) << k;
    with_mild += !by_mild.empty();
    std::uint32_t least_kept = UINT32_MAX;
    for (const Correspondence& c : by_mild) {
      EXPECT_GT(counts[c.model], limit) << k;
      least_kept = std::min(least_kept, counts[c.model]);
    }
    for (std::uint32_t m = 0; m < counts.size(); ++m) {  // none left out with more votes than one kept
      if (std::none_of(by_mild.begin(), by_mild.end(), [&](const Correspondence& c) { return c.model == m; })) {
        EXPECT_LE(counts[m], least_kept) << k;
      }
    }
  }
  std::printf("%d points without an upper outlier, %d of them with mild ones\n", without_outlier, with_mild);
  EXPECT_GT(with_mild, 5);
}

TEST(Voting, CandidateSpacingKeepsTheBestAndSpreadsTheRest) {
  const auto [points, normals, group] = wholePart(9);
  constexpr float kSpacing = 5.0f;
  const Points& model = lDatabase().model().points;
  Voter plain(lDatabase(), 6), spread(lDatabase(), 6, kSpacing);
  int bunched = 0, checked = 0;
  for (std::uint32_t k = 0; k < points.size(); k += 7) {
    std::vector<Correspondence> a, b;
    plain.votePoint(points, normals, k, group, a);
    spread.votePoint(points, normals, k, group, b);
    ASSERT_EQ(a.empty(), b.empty());
    if (a.empty()) continue;
    ++checked;
    EXPECT_EQ(a.front().model, b.front().model);  // the best-voted model point stays first
    EXPECT_LE(b.size(), 6u);
    for (std::size_t i = 0; i < b.size(); ++i)
      for (std::size_t j = i + 1; j < b.size(); ++j) EXPECT_GE((model[b[i].model] - model[b[j].model]).norm(), kSpacing);
    for (std::size_t i = 0; i < a.size(); ++i)
      for (std::size_t j = i + 1; j < a.size(); ++j) bunched += (model[a[i].model] - model[a[j].model]).norm() < kSpacing;
  }
  EXPECT_GT(checked, 20);
  EXPECT_GT(bunched, 0) << "without spacing no candidates were close: this test would not see the spacing work";
}

TEST(Voting, CandidateSpacingTakesTheOutliersBestFirst) {
  // The spaced candidates against a reference: each point's accumulator counted feature by
  // feature, all its upper outliers ordered by votes (ties by index, selectCandidates), then
  // each taken unless one taken before lies within the spacing, until 12 are taken.
  const WholePart part = wholePart(31);
  const auto& [points, normals, group] = part;
  const ModelDatabase& db = lDatabase();
  const Points& model = db.model().points;
  constexpr float kSpacing = 3.0f;
  constexpr int kKeep = 12;
  Voter spread(db, kKeep, kSpacing);
  int spaced_out = 0;
  for (std::uint32_t k = 0; k < points.size(); k += 5) {
    const std::vector<std::uint32_t> counts = countedVotes(db, part, k);
    const std::vector<std::size_t> ranked = selectCandidates(counts, static_cast<int>(model.size()));
    std::vector<std::uint32_t> expected;
    for (const std::size_t m : ranked) {
      if (expected.size() == static_cast<std::size_t>(kKeep)) break;
      const bool near = std::any_of(expected.begin(), expected.end(),
                                    [&](std::uint32_t e) { return (model[e] - model[m]).squaredNorm() < kSpacing * kSpacing; });
      spaced_out += near;
      if (!near) expected.push_back(static_cast<std::uint32_t>(m));
    }
    std::vector<Correspondence> got;
    spread.votePoint(points, normals, k, group, got);
    ASSERT_EQ(got.size(), expected.size()) << k;
    for (std::size_t c = 0; c < got.size(); ++c) EXPECT_EQ(got[c].model, expected[c]) << k << " rank " << c;
  }
  EXPECT_GT(spaced_out, 0) << "no outlier was spaced out: this test would not see the order matter";
}

TEST(Voting, LocalVotesPointAtTheTrueModelPoints) {
  Points points, normals;
  Rng rng(5);
  movedModel(test::randomPose(rng, Vec3(10, -20, 450)), points, normals);
  const auto candidates = voteNeighbourhoods(lDatabase(), points, normals, 40.0f, 1);
  const Points& model = lDatabase().model().points;
  const float near = 2.5f * lDatabase().model().sample_radius;
  int voted = 0, right = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (candidates[i].empty()) continue;
    ++voted;
    right += (model[candidates[i].front()] - model[3 * i]).norm() <= near;
  }
  EXPECT_GT(voted, static_cast<int>(points.size()) / 5);  // flat faces: many points have no outlier (eq. 11)
  EXPECT_GT(right, 3 * voted / 4) << right << " of " << voted << " candidates near the true model point";
}
