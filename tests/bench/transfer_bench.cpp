// Rig transfer end to end (prepared rig; per stage), ICT rig onto a remeshed
// ICT target when ../shared/data is present, else generated rigs.
//   transfer_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <filesystem>

#include <benchmark/benchmark.h>

#include "core/mesh_io.h"
#include "core/rig_io.h"
#include "core/synthetic_rig.h"
#include "core/transfer.h"

namespace {

struct Case {
  core::Rig rig;
  core::LandmarkSet landmarks;
  core::PreparedRig prepared;
  core::Mesh target;
  core::LandmarkSet target_landmarks;
  std::string name;
};

const Case& benchCase() {
  static Case c = [] {
    Case out;
    const std::filesystem::path data = std::filesystem::path(RIGPORT_SOURCE_DIR) / ".." / "shared" / "data" / "ict";
    auto rig = core::readRig(data / "source_face_skinned.glb");
    auto landmarks = core::readLandmarks(data / "source_face.landmarks.json");
    auto target = core::readMesh(data / "targets" / "id_s01_remesh.glb");
    auto target_landmarks = core::readLandmarks(data / "targets" / "id_s01_remesh.landmarks.json");
    if (rig && landmarks && target && target_landmarks) {
      out.rig = rig->rig;
      out.landmarks = *landmarks;
      out.target = target->mesh;
      out.target_landmarks = *target_landmarks;
      out.name = "ICT rig (11248 v, 53 shapes, 6 joints, 2 clips) -> id_s01_remesh (5884 v)";
    } else {
      const auto s = core::generateRig();
      const auto t = core::generateRig(core::randomHeadShape(4, 0.2), core::HeadResolution{80, 74, true, 0.3, 4});
      out.rig = s.rig;
      out.landmarks = s.landmarks;
      out.target = t.rig.mesh;
      out.target_landmarks = t.landmarks;
      out.name = "generated rigs (../shared/data absent)";
    }
    core::PrepareOptions prepare;
    prepare.threads = 1;
    out.prepared = std::move(*core::prepareRig(out.rig, out.landmarks, "source", prepare));
    return out;
  }();
  return c;
}

void BM_PrepareRig(benchmark::State& state) {
  const Case& c = benchCase();
  core::PrepareOptions prepare;
  prepare.threads = 1;
  for (auto _ : state) benchmark::DoNotOptimize(core::prepareRig(c.rig, c.landmarks, "source", prepare));
  state.SetLabel(c.name);
}
BENCHMARK(BM_PrepareRig)->Unit(benchmark::kMillisecond);

void BM_TransferPrepared(benchmark::State& state) {
  const Case& c = benchCase();
  core::TransferOptions options;
  options.threads = static_cast<int>(state.range(0));
  std::map<std::string, double> stage;
  for (auto _ : state) {
    auto r = core::transferRig(c.prepared, c.target, c.target_landmarks, "target", options);
    if (!r) {
      state.SkipWithError(r.error().message.c_str());
      return;
    }
    const auto& t = r->report;
    stage["warp"] += t.warp.warp_ms;
    stage["correspond"] += t.warp.correspond_ms;
    stage["weights"] += t.weights_ms;
    stage["joints"] += t.joints_ms;
    stage["shapes"] += t.shapes_ms;
    stage["attributes"] += t.attributes_ms;
  }
  for (const auto& [k, v] : stage) state.counters[k + "_ms"] = v / static_cast<double>(state.iterations());
  state.SetLabel(c.name + ", " + std::to_string(state.range(0)) + " thread(s)");
}
BENCHMARK(BM_TransferPrepared)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_WriteRigGlb(benchmark::State& state) {
  const Case& c = benchCase();
  auto r = core::transferRig(c.prepared, c.target, c.target_landmarks, "target");
  for (auto _ : state) benchmark::DoNotOptimize(core::encodeRigGlb(r->rig));
  state.SetLabel(c.name);
}
BENCHMARK(BM_WriteRigGlb)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
