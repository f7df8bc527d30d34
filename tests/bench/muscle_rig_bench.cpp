// The reference muscle rig (core/muscle_rig) on the ICT face: building it,
// evaluating one pose (the joy preset; evaluatePose, single-threaded) and
// baking its 15 presets as morph targets. Needs ../shared/data (a generated
// head is used otherwise, and the label says so).
#include <benchmark/benchmark.h>

#include "core/components/bake.h"
#include "core/components/pose.h"
#include "core/io/landmarks.h"
#include "core/io/rig_io.h"
#include "core/muscle_rig/muscle_rig.h"
#include "core/synthetic/synthetic_head.h"
#include "tests/test_support.h"

namespace {

struct Face {
  core::Rig rig;
  core::LandmarkSet landmarks;
  std::string label;
};

const Face& face() {
  static const Face loaded = [] {
    Face f;
    if (const auto data = rigport_test::sharedDataDir()) {
      auto rig = core::readRig(*data / "ict/source_face.glb");
      auto landmarks = core::readLandmarks(*data / "ict/source_face.landmarks.json");
      if (rig && landmarks) {
        f.rig = rig->rig;
        f.landmarks = *landmarks;
        f.label = "ict_face";
        return f;
      }
    }
    core::HeadShape shape;
    shape.mouth_open = 0.012;
    auto head = core::generateHead(shape);
    f.rig.mesh = head.mesh;
    f.landmarks = head.landmarks;
    f.label = "generated_head (no ../shared/data)";
    return f;
  }();
  return loaded;
}

const core::MuscleRig& muscleRig() {
  static const core::MuscleRig rig = *core::buildMuscleRig(face().rig.mesh, face().landmarks);
  return rig;
}

void BM_BuildMuscleRig(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(core::buildMuscleRig(face().rig.mesh, face().landmarks));
  state.SetLabel(face().label);
}

void BM_EvaluateMuscleRigPose(benchmark::State& state) {
  const auto controls = *core::presetControls(muscleRig().components, "joy");
  const core::Mesh& mesh = face().rig.mesh;
  for (auto _ : state) benchmark::DoNotOptimize(core::evaluatePose(mesh.positions, mesh.triangles, muscleRig().components, controls));
  state.SetLabel(face().label);
}

void BM_BakeMuscleRigPresets(benchmark::State& state) {
  for (auto _ : state) {
    state.PauseTiming();
    core::Rig rig = face().rig;
    state.ResumeTiming();
    benchmark::DoNotOptimize(core::bakePresets(rig, muscleRig().components));
  }
  state.SetLabel(face().label + ", " + std::to_string(muscleRig().components.presets.size()) + " presets");
}

}  // namespace

BENCHMARK(BM_BuildMuscleRig)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_EvaluateMuscleRigPose)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BakeMuscleRigPresets)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
