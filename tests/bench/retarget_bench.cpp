// Mocap retargeting, single-threaded: the ICT face (11248 vertices, cm) and the
// AnimFace nose clip (41 markers) cycled to 1000 frames, per distance method.
//   BM_MarkerDistances  the cacheable per (mesh, marker set) product
//   BM_Retarget         the job on cached distances + GLB encode (target <= 250 ms)
//   BM_RetargetOneOff   distances + job + encode
// Per-stage milliseconds are reported as counters (mean per iteration):
//   retarget_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// Needs ../shared/data (skips with an error otherwise).
#include <filesystem>
#include <map>
#include <optional>

#include <benchmark/benchmark.h>

#include "core/base/parallel.h"
#include "core/io/mesh_io.h"
#include "core/retarget/retarget.h"
#include "core/io/rig_io.h"
#include "core/io/trc_io.h"
#include "tests/test_support.h"

namespace {

constexpr int kFrames = 1000;

struct Case {
  core::Mesh mesh;
  core::LandmarkSet markers;
  core::MarkerTrajectories clip;
  std::map<core::DistanceMethod, core::MarkerDistances> distances;
  std::string error;
};

core::MarkerDistanceOptions distanceOptions(core::DistanceMethod method) {
  core::MarkerDistanceOptions o;
  o.method = method;
  const core::ScopedThreadCount o_threads(1);
  return o;
}

Case& benchCase() {
  static Case c = [] {
    Case out;
    const std::filesystem::path data = rigport_test::sharedDataDir().value_or(std::filesystem::path());
    auto mesh = core::readMesh(data / "ict" / "source_face.glb");
    auto markers = core::readLandmarks(data / "mocap" / "ict_markers.json");
    auto clip = core::readTrc(data / "mocap" / "animface_nose.trc");
    if (!mesh || !markers || !clip) {
      out.error = "../shared/data (ict/source_face.glb, mocap/) not readable";
      return out;
    }
    out.mesh = std::move(mesh->mesh);
    out.markers = std::move(*markers);
    // Cycle the clip (forwards then backwards, no jump) to kFrames frames.
    const int n = clip->frameCount();
    out.clip = *clip;
    out.clip.positions.resize(kFrames, clip->positions.cols());
    for (int f = 0; f < kFrames; ++f) {
      const int period = 2 * (n - 1), k = f % period;
      out.clip.positions.row(f) = clip->positions.row(k < n ? k : period - k);
    }
    out.clip.times = Eigen::VectorXd::LinSpaced(kFrames, 0.0, (kFrames - 1) / clip->data_rate);
    for (auto method : {core::DistanceMethod::kEuclidean, core::DistanceMethod::kGeodesic, core::DistanceMethod::kHybrid}) {
      auto d = core::computeMarkerDistances(out.mesh, out.markers, "source_face.glb", distanceOptions(method));
      if (!d) {
        out.error = d.error().message;
        return out;
      }
      out.distances.emplace(method, std::move(*d));
    }
    return out;
  }();
  return c;
}

core::DistanceMethod methodOf(const benchmark::State& state) { return static_cast<core::DistanceMethod>(state.range(0)); }

void BM_MarkerDistances(benchmark::State& state) {
  Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  for (auto _ : state) {
    auto d = core::computeMarkerDistances(c.mesh, c.markers, "source_face.glb", distanceOptions(methodOf(state)));
    benchmark::DoNotOptimize(d);
  }
  state.SetLabel(core::distanceMethodName(methodOf(state)));
}
BENCHMARK(BM_MarkerDistances)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void runRetarget(benchmark::State& state, bool one_off) {
  Case& c = benchCase();
  if (!c.error.empty()) return state.SkipWithError(c.error.c_str());
  core::RetargetOptions options;
  const core::ScopedThreadCount options_threads(1);
  std::map<std::string, double> stage;
  int rank = 0;
  std::size_t bytes = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    auto out = one_off ? core::retargetMocap(c.mesh, c.markers, c.clip, "source_face.glb", distanceOptions(methodOf(state)), options)
                       : core::retargetMocap(c.mesh, c.distances.at(methodOf(state)), c.clip, options);
    if (!out) return state.SkipWithError(out.error().message.c_str());
    const auto t1 = std::chrono::steady_clock::now();
    auto glb = core::encodeRigGlb(out->rig);
    if (!glb) return state.SkipWithError(glb.error().message.c_str());
    stage["encode_ms"] += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();
    stage["retarget_ms"] += std::chrono::duration<double, std::milli>(t1 - t0).count();
    for (const auto& [name, ms] : out->report.timings_ms) {
      if (one_off || name != "distances") stage[name + "_ms"] += ms;
    }
    rank = out->report.rank;
    bytes = glb->size();
  }
  for (const auto& [name, total] : stage) state.counters[name] = total / static_cast<double>(state.iterations());
  state.counters["rank"] = rank;
  state.counters["glb_MB"] = static_cast<double>(bytes) / 1e6;
  state.SetLabel(std::string(core::distanceMethodName(methodOf(state))) + ", 11248 v, 41 markers, 1000 frames, 1 thread");
}

void BM_Retarget(benchmark::State& state) { runRetarget(state, false); }
BENCHMARK(BM_Retarget)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_RetargetOneOff(benchmark::State& state) { runRetarget(state, true); }
BENCHMARK(BM_RetargetOneOff)->Arg(0)->Arg(2)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
