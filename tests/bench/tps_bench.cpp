// TPS factorisation, fit (back-substitution) and batch evaluation.
//   tps_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <random>

#include <benchmark/benchmark.h>

#include "core/base/parallel.h"
#include "core/solve/tps.h"

namespace {

Eigen::MatrixX3d randomPoints(Eigen::Index n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  Eigen::MatrixX3d p(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) p.row(i) << u(rng), u(rng), u(rng);
  return p;
}

void BM_TpsFactorize(benchmark::State& state) {
  const Eigen::MatrixX3d centres = randomPoints(state.range(0), 1);
  core::TpsOptions options;
  options.leave_one_out = state.range(1) != 0;
  for (auto _ : state) benchmark::DoNotOptimize(core::TpsFactorization::create(centres, options));
  state.SetLabel(options.leave_one_out ? "with leave-one-out" : "factorisation only");
}
BENCHMARK(BM_TpsFactorize)->Args({10, 1})->Args({44, 1})->Args({68, 1})->Args({1000, 0})->Args({3000, 0})
    ->Unit(benchmark::kMillisecond);

void BM_TpsFitReusingFactorisation(benchmark::State& state) {
  const Eigen::MatrixX3d centres = randomPoints(state.range(0), 1);
  core::TpsOptions options;
  options.leave_one_out = false;
  auto f = core::TpsFactorization::create(centres, options);
  const Eigen::MatrixX3d targets = 1.1 * centres + 0.01 * randomPoints(state.range(0), 2);
  for (auto _ : state) benchmark::DoNotOptimize(f->fit(targets));
}
BENCHMARK(BM_TpsFitReusingFactorisation)->Arg(68)->Arg(1000)->Arg(3000)->Unit(benchmark::kMillisecond);

void BM_TpsApply(benchmark::State& state) {
  const Eigen::MatrixX3d centres = randomPoints(state.range(1), 1);
  core::TpsOptions options;
  options.leave_one_out = false;
  const core::ScopedThreadCount options_threads(static_cast<int>(state.range(2)));
  auto warp = core::fitTps(centres, 1.1 * centres + 0.01 * randomPoints(state.range(1), 2), options);
  const Eigen::MatrixX3d points = randomPoints(state.range(0), 3);
  for (auto _ : state) benchmark::DoNotOptimize(warp->apply(points));
  state.SetItemsProcessed(state.iterations() * state.range(0));
  state.SetLabel(std::to_string(state.range(1)) + " centres, " + std::to_string(state.range(2)) + " thread(s)");
}
BENCHMARK(BM_TpsApply)
    ->Args({10000, 68, 1})->Args({100000, 68, 1})->Args({100000, 68, 2})
    ->Args({10000, 465, 1})->Args({11248, 465, 1})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
