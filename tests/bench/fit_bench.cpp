// The fit (core/fit/fit.h): the ICT reference prepared, and fitted to
// scan_s01 with and without its landmarks (per stage from the report), end to
// end as a job does it (read the scan and its landmarks, fit, encode the
// GLB), and on ~50k-point scans (s01 subdivided, an even cloud drawn on it).
// One thread. Needs ../shared/data: without it every benchmark is skipped
// with that message.
//   fit_bench --benchmark_repetitions=3 --benchmark_report_aggregates_only=true
#include <malloc.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include <benchmark/benchmark.h>

#include "core/base/parallel.h"
#include "core/fit/fit.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "tests/core/fit/fit_fixtures.h"
#include "tests/test_support.h"

namespace {

// The heap kept between iterations, as transfer_bench.cpp does (glibc
// returning and faulting in large blocks moved times by several ms).
const bool kHeapKept = [] {
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  return true;
}();

struct Case {
  std::filesystem::path data;
  rigport_test::FitReferenceCase reference;
  core::Rig rig;                  // as read, for the prepare benchmark
  core::LandmarkSet landmarks;    // the reference's
  std::filesystem::path scan_path, scan_landmarks_path;
  core::Mesh scan;                // scan_s01 (mm)
  core::LandmarkSet scan_landmarks;
  core::Mesh subdivided;          // scan_s01 split 1-to-4
  core::Mesh cloud;               // an even cloud of ~50k points on scan_s01, with normals
  std::string error;              // why the benchmarks are skipped
};

const Case& benchCase() {
  static const Case c = [] {
    Case out;
    const auto data = rigport_test::sharedDataDir();
    if (!data) {
      out.error = "../shared/data not found (set RIGPORT_SHARED_DATA): skipped";
      return out;
    }
    out.data = *data;
    const core::ScopedThreadCount threads(1);
    out.reference = rigport_test::loadIctFitReference(out.data);
    if (!out.reference.reference) {
      out.error = "ICT reference: " + out.reference.error;
      return out;
    }
    auto rig = core::readRig(out.data / "ict" / "source_face_skinned.glb");
    auto landmarks = core::readLandmarks(out.data / "ict" / "source_face.landmarks.json");
    out.scan_path = out.data / "scans" / "scan_s01.ply";
    out.scan_landmarks_path = out.data / "scans" / "scan_s01.landmarks.json";
    auto scan = core::readMesh(out.scan_path);
    auto scan_landmarks = core::readLandmarks(out.scan_landmarks_path);
    if (!rig || !landmarks || !scan || !scan_landmarks) {
      out.error = !rig ? rig.error().message : !landmarks ? landmarks.error().message
                : !scan ? scan.error().message : scan_landmarks.error().message;
      return out;
    }
    out.rig = std::move(rig->rig);
    out.landmarks = std::move(*landmarks);
    out.scan = std::move(scan->mesh);
    out.scan_landmarks = std::move(*scan_landmarks);
    out.subdivided = rigport_test::subdivideMidpoints(out.scan);
    // Spacing for ~50k points: dart throwing fills a surface at ~0.57 / spacing^2
    // (measured on ICT: 48,972 points at 1.45 mm on 1,795.5 cm^2).
    const double area = 0.5 * core::computeDoubleAreas(out.scan.positions, out.scan.triangles).sum();
    const Eigen::MatrixX3d normals = core::computeVertexNormals(out.scan.positions, out.scan.triangles);
    out.cloud = rigport_test::sampleSurfaceEvenly(out.scan, normals, std::sqrt(0.5735 * area / 50000.0), 600000, 7);
    return out;
  }();
  return c;
}

// Per-stage milliseconds of the fit's report, averaged over the iterations.
struct StageTimes {
  std::map<std::string, double> sum;
  void add(const core::FitReport& r) {
    sum["scan_ms"] += r.scan_ms;
    sum["align_ms"] += r.align_ms;
    sum["fit_ms"] += r.fit_ms;
    sum["gate_ms"] += r.gate_ms;
    sum["rebuild_ms"] += r.rebuild_ms;
  }
  void report(benchmark::State& state) const {
    for (const auto& [name, total] : sum) state.counters[name] = total / static_cast<double>(state.iterations());
  }
};

void BM_PrepareFitReference(benchmark::State& state) {
  const Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  const core::ScopedThreadCount threads(1);
  for (auto _ : state) {
    auto reference = core::prepareFitReference(c.reference.rig);
    if (!reference) return state.SkipWithError(reference.error().message.c_str());
    benchmark::DoNotOptimize(reference->laplacian.nonZeros());
  }
  state.counters["memory_mb"] = static_cast<double>(c.reference.reference->memoryBytes()) / 1e6;
  state.SetLabel("ICT (11,248 v), from its PreparedRig");
}
BENCHMARK(BM_PrepareFitReference)->Unit(benchmark::kMillisecond);

// The CLI's one-off cost before a fit: the rig prepared (prepareRig) and the fit's reference.
void BM_PrepareRigAndFitReference(benchmark::State& state) {
  const Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  const core::ScopedThreadCount threads(1);
  for (auto _ : state) {
    state.PauseTiming();
    core::Rig rig = c.rig;
    core::LandmarkSet landmarks = c.landmarks;
    state.ResumeTiming();
    auto prepared = core::prepareRig(std::move(rig), std::move(landmarks), "source_face_skinned.glb");
    if (!prepared) return state.SkipWithError(prepared.error().message.c_str());
    auto reference = core::prepareFitReference(std::make_shared<const core::PreparedRig>(std::move(*prepared)));
    if (!reference) return state.SkipWithError(reference.error().message.c_str());
    benchmark::DoNotOptimize(reference->laplacian.nonZeros());
  }
  state.SetLabel("ICT");
}
BENCHMARK(BM_PrepareRigAndFitReference)->Unit(benchmark::kMillisecond);

// fitScan on a prepared reference; arg 1: with the scan's 12 landmarks, 0: searched.
void fitBenchmark(benchmark::State& state, const core::Mesh& scan, const std::string& label) {
  const Case& c = benchCase();
  const bool with_landmarks = state.range(0) == 1;
  const core::ScopedThreadCount threads(1);
  StageTimes times;
  std::string verdict;
  for (auto _ : state) {
    auto fit = core::fitScan(*c.reference.reference, scan, with_landmarks ? c.scan_landmarks : core::LandmarkSet{},
                             label);
    if (!fit) return state.SkipWithError(fit.error().message.c_str());
    times.add(fit->report);
    verdict = fit->report.verdict;
  }
  times.report(state);
  state.SetLabel(label + " (" + std::to_string(scan.vertexCount()) + " points), " +
                 (with_landmarks ? "landmarks" : "search") + ", verdict " + verdict);
}

void BM_FitScan(benchmark::State& state) {
  const Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  fitBenchmark(state, c.scan, "scan_s01");
}
BENCHMARK(BM_FitScan)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);

void BM_FitScanSubdivided(benchmark::State& state) {
  const Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  fitBenchmark(state, c.subdivided, "scan_s01 1-to-4");
}
BENCHMARK(BM_FitScanSubdivided)->Arg(1)->Unit(benchmark::kMillisecond);

void BM_FitScanCloud50k(benchmark::State& state) {
  const Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  fitBenchmark(state, c.cloud, "cloud on scan_s01");
}
BENCHMARK(BM_FitScanCloud50k)->Arg(1)->Unit(benchmark::kMillisecond);

// A job's work after its reference is prepared (arg 0: taken from a cache)
// or with it (arg 1: read and prepared, as a one-off CLI run): read the
// scan and its landmarks, fit, encode the GLB.
void BM_FitEndToEnd(benchmark::State& state) {
  const Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  const bool prepare = state.range(0) == 1;
  const core::ScopedThreadCount threads(1);
  std::map<std::string, double> ms;
  StageTimes times;
  std::size_t bytes = 0;
  using Clock = std::chrono::steady_clock;
  const auto since = [](Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); };
  for (auto _ : state) {
    auto t = Clock::now();
    std::shared_ptr<const core::FitReference> reference = c.reference.reference;
    if (prepare) {
      auto rig = core::readRig(c.data / "ict" / "source_face_skinned.glb");
      auto landmarks = core::readLandmarks(c.data / "ict" / "source_face.landmarks.json");
      if (!rig || !landmarks) return state.SkipWithError("the ICT reference did not read");
      auto prepared = core::prepareRig(std::move(rig->rig), std::move(*landmarks), "source_face_skinned.glb");
      if (!prepared) return state.SkipWithError(prepared.error().message.c_str());
      auto fit_reference = core::prepareFitReference(std::make_shared<const core::PreparedRig>(std::move(*prepared)));
      if (!fit_reference) return state.SkipWithError(fit_reference.error().message.c_str());
      reference = std::make_shared<const core::FitReference>(std::move(*fit_reference));
      ms["prepare_ms"] += since(t);
      t = Clock::now();
    }
    auto scan = core::readMesh(c.scan_path);
    auto scan_landmarks = core::readLandmarks(c.scan_landmarks_path);
    if (!scan || !scan_landmarks) return state.SkipWithError("scan_s01 did not read");
    ms["read_ms"] += since(t);
    t = Clock::now();
    auto fit = core::fitScan(*reference, scan->mesh, *scan_landmarks, "scan_s01.ply");
    if (!fit) return state.SkipWithError(fit.error().message.c_str());
    times.add(fit->report);
    t = Clock::now();
    auto glb = core::encodeRigGlb(fit->rig);
    if (!glb) return state.SkipWithError(glb.error().message.c_str());
    ms["write_ms"] += since(t);
    bytes = glb->size();
  }
  for (const auto& [name, total] : ms) state.counters[name] = total / static_cast<double>(state.iterations());
  times.report(state);
  state.counters["glb_bytes"] = static_cast<double>(bytes);
  state.SetLabel(std::string("scan_s01 with landmarks, reference ") + (prepare ? "read and prepared" : "cached"));
}
BENCHMARK(BM_FitEndToEnd)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
