// Micro-benchmarks of the pipeline's stages on a simulated bin of 16 built-in caps (about 100 000
// scan points) and the cap's 4000-point model. Run: build/bench/binpose_bench_stages
// (--benchmark_repetitions=5 --benchmark_report_aggregates_only=true for medians).
#include <binpose/clique.hpp>
#include <binpose/detector.hpp>
#include <binpose/geometry.hpp>
#include <binpose/kdtree.hpp>
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/normals.hpp>
#include <binpose/planes.hpp>
#include <binpose/refine.hpp>
#include <binpose/scene.hpp>
#include <binpose/shapes.hpp>
#include <binpose/simulation.hpp>
#include <binpose/voting.hpp>

#include "stage_settings.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numeric>

using namespace binpose;

namespace {

/// The bin, the model, its database and the default parameters, made once.
struct Fixture {
  Mesh mesh = builtinPart("cap");
  OrientedModel model = prepareModel(mesh, ModelParams{});
  ModelDatabase db = ModelDatabase::build(model, defaultQuantization(model.diameter));
  /// As the detector runs them (plane_min_area resolved from the model).
  StageSettings params = Detector(db, scaledToModel(defaultPreset(), model.diameter)).settings();
  SimulatedScene bin = [this] {
    SimulationParams sp;
    sp.seed = 7;
    return simulateBin(mesh, sp);
  }();
  PointGrid scan_grid{bin.cloud.points};
  PreparedScene scene = prepareScene(bin.cloud.points, scan_grid, subsampleScene(bin.cloud.points, params.rho_sub, params.subsampling, params.seed),
                                     params.k_normals, params.viewpoint);
  std::vector<std::vector<std::uint32_t>> groups = makeSubGroups(scene.points, params.eta, params.r, 8);
  /// The sub-group of median size.
  const std::vector<std::uint32_t>& medianGroup() const { return groups[groups.size() / 2]; }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

void BM_BuildDatabase(benchmark::State& state) {
  const Fixture& f = fixture();
  const auto q = defaultQuantization(f.model.diameter);
  for (auto _ : state) benchmark::DoNotOptimize(ModelDatabase::build(f.model, q));
}
BENCHMARK(BM_BuildDatabase)->Unit(benchmark::kMillisecond);

void BM_Subsample(benchmark::State& state) {
  const Fixture& f = fixture();
  const float spacing = 1.0f / std::sqrt(f.params.rho_sub);
  for (auto _ : state) benchmark::DoNotOptimize(voxelSubsample(f.bin.cloud.points, spacing));
  state.counters["scan_points"] = static_cast<double>(f.bin.cloud.size());
}
BENCHMARK(BM_Subsample)->Unit(benchmark::kMillisecond);

// The scan's neighbour index: binpose's grid (Arg 0) against nanoflann's kd-tree (Arg 1), the
// peer it replaced. Built once per scan.
void BM_ScanIndex(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    if (state.range(0) == 0) benchmark::DoNotOptimize(PointGrid(f.bin.cloud.points));
    else benchmark::DoNotOptimize(KdTree(f.bin.cloud.points));
  }
  state.SetLabel(state.range(0) == 0 ? "grid" : "kd-tree");
}
BENCHMARK(BM_ScanIndex)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The queries ICP and the score ask: the nearest scan point within a gate (ICP's first gate,
// Arg 0 = grid, 1 = kd-tree), of 100 000 points near the scan (within about 1.5 mm of it).
void BM_ScanNearest(benchmark::State& state) {
  const Fixture& f = fixture();
  const Points& scan = f.bin.cloud.points;
  const PointGrid grid(scan);
  const KdTree tree(scan);
  Rng rng(3);
  Points queries;
  for (int i = 0; i < 100000; ++i) {
    const Vec3 offset(float(rng.uniform()) - 0.5f, float(rng.uniform()) - 0.5f, float(rng.uniform()) - 0.5f);
    queries.push_back(scan[rng.below(scan.size())] + 3.0f * offset);
  }
  const float gate = f.params.icp_max_distance;
  for (auto _ : state) {
    std::size_t found = 0;
    for (const Vec3& q : queries) {
      std::uint32_t j;
      float d2;
      if (state.range(0) == 0) found += grid.nearest(q, gate, j, d2);
      else found += tree.nearest(q, j, d2) && d2 <= gate * gate;
    }
    benchmark::DoNotOptimize(found);
  }
  state.SetLabel(state.range(0) == 0 ? "grid" : "kd-tree");
}
BENCHMARK(BM_ScanNearest)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Plane fits of the sampled points on the full scan (5.2.2), with k = Arg neighbours (6: the
// default preset's k_normals; 12: twice that, fast's 8 lying between).
void BM_Normals(benchmark::State& state) {
  const Fixture& f = fixture();
  const int k = static_cast<int>(state.range(0));
  for (auto _ : state)
    benchmark::DoNotOptimize(estimateNormals(f.scan_grid, f.bin.cloud.points, f.scene.points, k, Vec3::Zero()));
  state.counters["points"] = static_cast<double>(f.scene.points.size());
}
BENCHMARK(BM_Normals)->Arg(6)->Arg(12)->Unit(benchmark::kMillisecond);

// The same points by index with k = 8 (fast's k_normals), their neighbours through the grid
// (Arg 0) or from the depth image's pixel neighbours where those are proved the nearest, the
// rest through the grid (Arg 1; the pixel index built in the loop too): the same normals.
void BM_NormalsAtScanPoints(benchmark::State& state) {
  const Fixture& f = fixture();
  const bool from_pixels = state.range(0) == 1;
  for (auto _ : state) {
    const PixelNeighbours pixels(f.bin.cloud);
    benchmark::DoNotOptimize(estimateNormals(f.scan_grid, from_pixels ? &pixels : nullptr, f.bin.cloud.points,
                                             f.scene.scan_index, 8, Vec3::Zero()));
  }
  state.SetLabel(from_pixels ? "pixels" : "grid");
}
BENCHMARK(BM_NormalsAtScanPoints)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// The depth image's pixel index alone (Arg 0), and the 8 nearest of the sampled points from it
// (Arg 1: the index built once; the points it cannot prove are counted, not searched).
void BM_PixelNeighbours(benchmark::State& state) {
  const Fixture& f = fixture();
  if (state.range(0) == 0) {
    for (auto _ : state) benchmark::DoNotOptimize(PixelNeighbours(f.bin.cloud));
    return;
  }
  const PixelNeighbours pixels(f.bin.cloud);
  std::uint32_t idx[8];
  float d2[8];
  std::size_t missed = 0;
  for (auto _ : state) {
    missed = 0;
    for (const auto i : f.scene.scan_index) missed += !pixels.knn(i, 8, idx, d2);
    benchmark::DoNotOptimize(idx);
  }
  state.counters["missed"] = static_cast<double>(missed);
}
BENCHMARK(BM_PixelNeighbours)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_Planes(benchmark::State& state) {  // the bin's floor and walls found in the sampled scene
  const Fixture& f = fixture();
  std::size_t flat = 0;
  for (auto _ : state) {
    const auto flags = largePlanes(f.scene.points, f.scene.normals, f.params.rho_sub, planeParams(f.params));
    flat = static_cast<std::size_t>(std::count(flags.begin(), flags.end(), 1));
  }
  state.counters["points"] = static_cast<double>(f.scene.points.size());
  state.counters["on_planes"] = static_cast<double>(flat);
}
BENCHMARK(BM_Planes)->Unit(benchmark::kMillisecond);

/// 4.3-4.4 on the median sub-group: Voter on one thread, ParallelVoter with its points shared
/// among threads (the same pairs).
template <class V>
void BM_VoteSubGroup(benchmark::State& state) {
  const Fixture& f = fixture();
  V voter(f.db);
  std::vector<Correspondence> out;
  for (auto _ : state) {
    out.clear();
    voter.vote(f.scene.points, f.scene.normals, f.medianGroup(), out);
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["group_points"] = static_cast<double>(f.medianGroup().size());
}
BENCHMARK_TEMPLATE(BM_VoteSubGroup, Voter)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_VoteSubGroup, ParallelVoter)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LocalVotes(benchmark::State& state) {  // the default local votes, every sampled point voting once
  const Fixture& f = fixture();
  const StageSettings& p = f.params;
  std::vector<std::uint32_t> all(f.scene.points.size());
  std::iota(all.begin(), all.end(), 0u);
  for (auto _ : state) {  // as the detector does it: partners thinned, candidates spaced
    const auto partners = voxelSubsample(f.scene.points, p.partner_spacing);
    NeighbourhoodVoter voter(f.db, f.scene.points, f.scene.normals, p.vote_radius, p.candidates_per_point, partners,
                             p.candidate_spacing);
    voter.vote(all);
    benchmark::DoNotOptimize(voter.release());
  }
}
BENCHMARK(BM_LocalVotes)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ConsistencyGraph(benchmark::State& state) {  // 4.5, eq. 13-16, on the default preset's candidates of the median sub-group
  const Fixture& f = fixture();
  const StageSettings& p = f.params;
  const auto partners = voxelSubsample(f.scene.points, p.partner_spacing);
  NeighbourhoodVoter voter(f.db, f.scene.points, f.scene.normals, p.vote_radius, p.candidates_per_point, partners,
                           p.candidate_spacing);
  voter.vote(f.medianGroup());
  std::vector<Correspondence> cps;
  for (const auto i : f.medianGroup())
    for (const auto m : voter.candidates(i)) cps.push_back({i, m});
  for (auto _ : state) benchmark::DoNotOptimize(consistencyGraph(cps, f.scene.points, f.model.points, p.e_gmax));
  state.counters["vertices"] = static_cast<double>(cps.size());
}
BENCHMARK(BM_ConsistencyGraph)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_CliqueSearch(benchmark::State& state) {  // 4.5 on the median sub-group's candidate pairs
  const Fixture& f = fixture();
  std::vector<Correspondence> cps;
  Voter(f.db).vote(f.scene.points, f.scene.normals, f.medianGroup(), cps);
  const Graph g = consistencyGraph(cps, f.scene.points, f.model.points, f.params.e_gmax);
  for (auto _ : state) benchmark::DoNotOptimize(maximumClique(g, f.params.clique_work_limit));
  state.counters["vertices"] = static_cast<double>(cps.size());
}
BENCHMARK(BM_CliqueSearch)->Unit(benchmark::kMillisecond);

void BM_Refine(benchmark::State& state) {  // point-to-plane ICP from 1 mm and 2 degrees off the truth
  const Fixture& f = fixture();
  const Pose truth = f.bin.instances.front().pose;
  Pose start = truth;
  start.translation() += Vec3(0.6f, -0.5f, 0.6f);
  start.linear() = start.linear() * Eigen::AngleAxisf(0.035f, Vec3(1, 1, 0).normalized()).toRotationMatrix();
  const IcpParams icp{f.params.icp_iterations, f.params.icp_max_distance, f.params.verify_tolerance, Vec3::Zero(), {}, nullptr};
  // The model points the detector pairs up for icp_model_points = the argument (0: all), made
  // ready once, as the detector does.
  OrientedPoints share = evenShare(f.model.points, f.model.normals, static_cast<std::size_t>(state.range(0)));
  const PreparedModel m(std::move(share.points), std::move(share.normals));
  for (auto _ : state) benchmark::DoNotOptimize(refinePose(start, m, f.bin.cloud.points, f.scan_grid, icp));
  state.counters["model_points"] = static_cast<double>(m.points().size());
}
BENCHMARK(BM_Refine)->Arg(0)->Arg(1000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
