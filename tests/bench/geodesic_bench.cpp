// Heat-method geodesics (core/solve/geodesic.cpp), single-threaded: factorisation,
// 41 distance fields (one per AnimFace mocap marker), and both together, on
// the ICT face (../shared/data/ict/source_face.glb, 11248 vertices, markers
// from ../shared/data/mocap/ict_markers.json) and on a generated head of
// similar size. Target: factorise + 41 fields <= 100 ms.
// Run: geodesic_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <filesystem>
#include <optional>
#include <string>

#include <benchmark/benchmark.h>

#include "core/base/parallel.h"
#include "core/solve/geodesic.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

constexpr int kSources = 41;

struct Case {
  core::Mesh mesh;
  std::vector<core::SurfacePoint> sources;
  std::string error;  // non-empty: skip with this message
};

// Spread `count` sources over the mesh's triangles when no markers are given.
std::vector<core::SurfacePoint> spreadSources(const core::Mesh& mesh, int count) {
  std::vector<core::SurfacePoint> sources;
  for (int s = 0; s < count; ++s) {
    core::SurfacePoint p;
    p.face = static_cast<int>((mesh.triangleCount() * (2 * s + 1)) / (2 * count));
    p.barycentric = Eigen::Vector3d::Constant(1.0 / 3.0);
    sources.push_back(p);
  }
  return sources;
}

const Case& ictFace() {
  static const Case c = [] {
    Case out;
    const std::filesystem::path data = rigport_test::sharedDataDir().value_or(std::filesystem::path());
    auto loaded = core::readMesh(data / "ict" / "source_face.glb");
    if (!loaded) {
      out.error = "ICT face not available: " + loaded.error().message;
      return out;
    }
    out.mesh = std::move(loaded->mesh);
    auto markers = core::readLandmarks(data / "mocap" / "ict_markers.json");
    if (markers) {
      for (const auto& m : markers->landmarks) {
        if (m.kind == core::LandmarkKind::kFace) out.sources.push_back({m.face, m.barycentric});
      }
    }
    if (out.sources.size() != kSources) out.sources = spreadSources(out.mesh, kSources);
    return out;
  }();
  return c;
}

const Case& generatedHead() {
  static const Case c = [] {
    Case out;
    core::HeadShape shape;
    shape.mouth_open = 0.03;
    core::HeadResolution resolution;
    resolution.columns = 128;  // 129 x 89 = 11481 vertices, about the ICT face
    resolution.rows = 88;
    resolution.jitter = 0.2;
    out.mesh = core::generateHead(shape, resolution).mesh;
    out.sources = spreadSources(out.mesh, kSources);
    return out;
  }();
  return c;
}

const Case& caseFor(const benchmark::State& state) { return state.range(0) == 0 ? ictFace() : generatedHead(); }

core::GeodesicOptions optionsFor(const benchmark::State& state) {
  core::GeodesicOptions options;
  options.average_boundary_conditions = state.range(1) != 0;
  return options;
}

void setLabel(benchmark::State& state, const Case& c) {
  state.SetLabel(std::string(state.range(0) == 0 ? "ict_face" : "generated_head") + " V=" +
                 std::to_string(c.mesh.vertexCount()) +
                 (state.range(1) != 0 ? " neumann+dirichlet" : " neumann"));
}

void BM_GeodesicFactorise(benchmark::State& state) {
  const Case& c = caseFor(state);
  if (!c.error.empty()) {
    state.SkipWithError(c.error.c_str());
    return;
  }
  for (auto _ : state) {
    auto solver = core::GeodesicSolver::create(c.mesh, "bench", optionsFor(state));
    if (!solver) {
      state.SkipWithError(solver.error().message.c_str());
      return;
    }
    benchmark::DoNotOptimize(solver->vertexCount());
  }
  setLabel(state, c);
}

void BM_GeodesicDistances41(benchmark::State& state) {
  const Case& c = caseFor(state);
  if (!c.error.empty()) {
    state.SkipWithError(c.error.c_str());
    return;
  }
  auto solver = core::GeodesicSolver::create(c.mesh, "bench", optionsFor(state));
  if (!solver) {
    state.SkipWithError(solver.error().message.c_str());
    return;
  }
  const core::ScopedThreadCount one_thread(1);
  for (auto _ : state) {
    Eigen::MatrixXd d = solver->distances(c.sources);
    benchmark::DoNotOptimize(d.data());
  }
  setLabel(state, c);
}

// The budgeted operation: a fresh solver and 41 fields.
void BM_GeodesicFactoriseAnd41(benchmark::State& state) {
  const Case& c = caseFor(state);
  if (!c.error.empty()) {
    state.SkipWithError(c.error.c_str());
    return;
  }
  const core::ScopedThreadCount one_thread(1);
  for (auto _ : state) {
    auto solver = core::GeodesicSolver::create(c.mesh, "bench", optionsFor(state));
    if (!solver) {
      state.SkipWithError(solver.error().message.c_str());
      return;
    }
    Eigen::MatrixXd d = solver->distances(c.sources);
    benchmark::DoNotOptimize(d.data());
  }
  setLabel(state, c);
}

// Args: {mesh: 0 = ICT face, 1 = generated head; boundary averaging: 1 = on (default), 0 = off}.
void meshArgs(benchmark::internal::Benchmark* b) {
  for (int mesh : {0, 1}) {
    for (int average : {1, 0}) b->Args({mesh, average});
  }
}

BENCHMARK(BM_GeodesicFactorise)->Apply(meshArgs)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GeodesicDistances41)->Apply(meshArgs)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_GeodesicFactoriseAnd41)->Apply(meshArgs)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
