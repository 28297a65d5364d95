// Micro-benchmarks of the offline stages. Run: build/bench/binpose_bench_stages
#include <binpose/model.hpp>
#include <binpose/model_database.hpp>
#include <binpose/shapes.hpp>

#include <benchmark/benchmark.h>

namespace {

void BM_PrepareModel(benchmark::State& state) {
  const binpose::Mesh mesh = binpose::makeSphere(30.0f, 4);
  binpose::ModelParams params;
  params.num_points = static_cast<int>(state.range(0));
  for (auto _ : state) benchmark::DoNotOptimize(binpose::prepareModel(mesh, params));
}
BENCHMARK(BM_PrepareModel)->Arg(1000)->Arg(4000)->Unit(benchmark::kMillisecond);

void BM_BuildDatabase(benchmark::State& state) {
  binpose::ModelParams params;
  params.num_points = static_cast<int>(state.range(0));
  const binpose::OrientedModel model = binpose::prepareModel(binpose::makeBox({60, 40, 20}, 4), params);
  const auto q = binpose::defaultQuantization(model.diameter);
  for (auto _ : state) benchmark::DoNotOptimize(binpose::ModelDatabase::build(model, q));
}
BENCHMARK(BM_BuildDatabase)->Arg(1000)->Arg(4000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
