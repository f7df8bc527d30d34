// Whole warp + dense correspondence (prepared source), per stage.
// Uses the ICT data in ../shared/data when present (MANIFEST.md), else
// generated heads of similar size.
//   warp_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <filesystem>

#include <benchmark/benchmark.h>

#include "core/base/parallel.h"
#include "core/io/mesh_io.h"
#include "core/synthetic/synthetic_head.h"
#include "core/correspond/warp_job.h"
#include "tests/test_support.h"

namespace {

struct Case {
  core::PreparedSource source;
  core::Mesh target;
  core::LandmarkSet target_landmarks;
  std::string name;
};

const Case& ictCase() {
  static Case c = [] {
    Case out;
    const std::filesystem::path data = rigport_test::sharedDataDir().value_or(std::filesystem::path()) / "ict";
    core::PrepareOptions prepare;
    const core::ScopedThreadCount prepare_threads(1);
    auto mesh = core::readMesh(data / "source_face.glb");
    auto landmarks = core::readLandmarks(data / "source_face.landmarks.json");
    auto target = core::readMesh(data / "targets" / "id_s01_remesh.glb");
    auto target_landmarks = core::readLandmarks(data / "targets" / "id_s01_remesh.landmarks.json");
    if (mesh && landmarks && target && target_landmarks) {
      out.source = std::move(*core::prepareSource(mesh->mesh, *landmarks, "source_face.glb", prepare));
      out.target = target->mesh;
      out.target_landmarks = *target_landmarks;
      out.name = "ICT source_face (11248 v) -> id_s01_remesh (5884 v)";
    } else {
      const auto s = core::generateHead(core::HeadShape{}, core::HeadResolution{110, 100});
      const auto t = core::generateHead(core::randomHeadShape(4, 0.2), core::HeadResolution{80, 74, true, 0.3, 4});
      out.source = std::move(*core::prepareSource(s.mesh, s.landmarks, "generated", prepare));
      out.target = t.mesh;
      out.target_landmarks = t.landmarks;
      out.name = "generated heads (../shared/data absent)";
    }
    return out;
  }();
  return c;
}

void runCase(benchmark::State& state, core::WarpOptions options) {
  const Case& c = ictCase();
  const core::ScopedThreadCount options_threads(1);
  double warp = 0, correspond = 0;
  for (auto _ : state) {
    auto r = core::runWarp(c.source, c.target, c.target_landmarks, "target", options);
    if (!r) {
      state.SkipWithError(r.error().message.c_str());
      return;
    }
    warp += r->report.warp_ms;
    correspond += r->report.correspond_ms;
  }
  state.counters["warp_ms"] = warp / static_cast<double>(state.iterations());
  state.counters["correspond_ms"] = correspond / static_cast<double>(state.iterations());
  state.SetLabel(c.name);
}

void BM_WarpCorrespondPlain(benchmark::State& state) { runCase(state, core::plainWarpOptions()); }
BENCHMARK(BM_WarpCorrespondPlain)->Unit(benchmark::kMillisecond);

// No dense-map rounds, one local round: [1]'s accuracy limits hold
// (ict_warp_test runs them on this pipeline too) at about the plain cost.
void BM_WarpCorrespondLight(benchmark::State& state) { runCase(state, core::lightWarpOptions()); }
BENCHMARK(BM_WarpCorrespondLight)->Unit(benchmark::kMillisecond);

void BM_WarpCorrespondDefault(benchmark::State& state) { runCase(state, core::WarpOptions{}); }
BENCHMARK(BM_WarpCorrespondDefault)->Unit(benchmark::kMillisecond);

void BM_PrepareSource(benchmark::State& state) {
  const Case& c = ictCase();
  core::PrepareOptions prepare;
  const core::ScopedThreadCount prepare_threads(1);
  for (auto _ : state) {
    benchmark::DoNotOptimize(core::prepareSource(c.source.mesh, c.source.landmarks, "source", prepare));
  }
  state.SetLabel(c.name);
}
BENCHMARK(BM_PrepareSource)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
