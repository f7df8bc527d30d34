// Rig transfer (prepared rig, per stage; and end to end), ICT rig onto a remeshed
// ICT target when ../shared/data is present, else generated rigs.
//   transfer_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>

#include <benchmark/benchmark.h>

#include "core/base/parallel.h"
#include "core/io/landmarks.h"
#include "core/geometry/mesh.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/muscle_rig/muscle_rig.h"
#include "core/synthetic/synthetic_rig.h"
#include "core/transfer/transfer.h"
#include "tests/test_support.h"

namespace {

// The process keeps the heap it frees (no trimming, large blocks from the
// heap): otherwise whether glibc hands the ~15 MB freed with an iteration's
// rig back to the OS, to fault it in again in the next one, depends on the
// order of frees, and moved the end-to-end time by 3-6 ms between builds
// with the same work (docs/journal/BENCHMARKS_HISTORY.md, 2026-11-22 night).
const bool kHeapKept = [] {
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  return true;
}();

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
    const std::filesystem::path data = rigport_test::sharedDataDir().value_or(std::filesystem::path()) / "ict";
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
    const core::ScopedThreadCount prepare_threads(1);
    out.prepared = std::move(*core::prepareRig(out.rig, out.landmarks, "source", prepare));
    return out;
  }();
  return c;
}

void BM_PrepareRig(benchmark::State& state) {
  const Case& c = benchCase();
  core::PrepareOptions prepare;
  const core::ScopedThreadCount prepare_threads(1);
  for (auto _ : state) benchmark::DoNotOptimize(core::prepareRig(c.rig, c.landmarks, "source", prepare));
  state.SetLabel(c.name);
}
BENCHMARK(BM_PrepareRig)->Unit(benchmark::kMillisecond);

void BM_TransferPrepared(benchmark::State& state) {
  const Case& c = benchCase();
  core::TransferOptions options;
  const core::ScopedThreadCount options_threads(static_cast<int>(state.range(0)));
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

// The same transfer with the reference muscle rig's components document
// (core/muscle_rig, built on the source face) carried to the target: what the
// components add to a rig transfer (docs/COMPONENTS.md), on one thread.
// Compare with BM_TransferPrepared/1 of the same run; components_ms is the
// report's own time for that step.
void BM_TransferWithMuscleRigComponents(benchmark::State& state) {
  static const core::PreparedRig prepared = [] {
    const Case& c = benchCase();
    const core::ScopedThreadCount prepare_threads(1);
    core::PreparedRig out = std::move(*core::prepareRig(c.rig, c.landmarks, "source"));
    if (auto muscle_rig = core::buildMuscleRig(c.rig.mesh, c.landmarks)) out.components = std::move(muscle_rig->components);
    return out;
  }();
  const Case& c = benchCase();
  core::TransferOptions options;
  const core::ScopedThreadCount options_threads(1);
  double components = 0;
  for (auto _ : state) {
    auto r = core::transferRig(prepared, c.target, c.target_landmarks, "target", options);
    if (!r || !r->components) {
      state.SkipWithError(r ? "no components document (the muscle rig could not be built on the source)"
                            : r.error().message.c_str());
      return;
    }
    components += r->report.components_ms;
  }
  state.counters["components_ms"] = components / static_cast<double>(state.iterations());
  state.SetLabel(c.name + ", muscle rig components, 1 thread");
}
BENCHMARK(BM_TransferWithMuscleRigComponents)->Unit(benchmark::kMillisecond);

// Each triangle split into four at its edge midpoints (shared midpoints
// merged): the surface is unchanged, the vertex count roughly quadruples.
core::Mesh subdivideMidpoints(const core::Mesh& mesh) {
  std::map<std::pair<int, int>, int> midpoint;
  std::vector<Eigen::RowVector3d> positions;
  for (Eigen::Index v = 0; v < mesh.vertexCount(); ++v) positions.push_back(mesh.positions.row(v));
  auto mid = [&](int a, int b) {
    const auto key = std::minmax(a, b);
    auto [it, added] = midpoint.try_emplace({key.first, key.second}, static_cast<int>(positions.size()));
    if (added) positions.push_back(0.5 * (mesh.positions.row(a) + mesh.positions.row(b)));
    return it->second;
  };
  core::Mesh out;
  out.triangles.resize(4 * mesh.triangleCount(), 3);
  for (Eigen::Index f = 0; f < mesh.triangleCount(); ++f) {
    const int a = mesh.triangles(f, 0), b = mesh.triangles(f, 1), c = mesh.triangles(f, 2);
    const int ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    out.triangles.row(4 * f) << a, ab, ca;
    out.triangles.row(4 * f + 1) << ab, b, bc;
    out.triangles.row(4 * f + 2) << ca, bc, c;
    out.triangles.row(4 * f + 3) << ab, bc, ca;
  }
  out.positions.resize(static_cast<Eigen::Index>(positions.size()), 3);
  for (std::size_t v = 0; v < positions.size(); ++v) out.positions.row(static_cast<Eigen::Index>(v)) = positions[v];
  out.normals = core::computeVertexNormals(out.positions, out.triangles);
  return out;
}

// The large case: a ~100k-vertex target and 150 shapes, on 2 threads,
// transfer + GLB write. ICT rig with its shapes repeated to 150 onto
// id_s01_remesh subdivided twice (94k vertices); landmarks as positions.
struct LargeCase {
  core::PreparedRig prepared;
  core::Mesh target;
  core::LandmarkSet target_landmarks;
  std::string name;
};

const LargeCase& largeCase() {
  static LargeCase c = [] {
    LargeCase out;
    const Case& base = benchCase();
    core::Rig rig = base.rig;
    const std::size_t original = rig.morph_targets.size();
    for (std::size_t k = original; k < 150 && original > 0; ++k) {
      core::MorphTarget copy = rig.morph_targets[k % original];
      copy.name += "_copy" + std::to_string(k / original);
      rig.morph_targets.push_back(std::move(copy));
    }
    // Morph-weight channels and default weights follow the repeated shapes.
    for (auto& animation : rig.animations) {
      for (auto& channel : animation.channels) {
        if (channel.path != core::AnimationPath::kWeights || channel.values.cols() == 0) continue;
        const Eigen::MatrixXd values = channel.values;
        channel.values.resize(values.rows(), static_cast<Eigen::Index>(rig.morph_targets.size()));
        for (Eigen::Index k = 0; k < channel.values.cols(); ++k) channel.values.col(k) = values.col(k % values.cols());
      }
    }
    if (rig.morph_default_weights.size() > 0) {
      const Eigen::VectorXd weights = rig.morph_default_weights;
      rig.morph_default_weights.resize(static_cast<Eigen::Index>(rig.morph_targets.size()));
      for (Eigen::Index k = 0; k < rig.morph_default_weights.size(); ++k) {
        rig.morph_default_weights(k) = weights(k % weights.size());
      }
    }
    out.prepared = std::move(*core::prepareRig(rig, base.landmarks, "source"));
    out.target = subdivideMidpoints(subdivideMidpoints(base.target));
    const auto positions = core::resolveLandmarks(base.target_landmarks, base.target, "target");
    out.target_landmarks = base.target_landmarks;
    for (std::size_t i = 0; i < out.target_landmarks.landmarks.size(); ++i) {
      core::Landmark& lm = out.target_landmarks.landmarks[i];
      lm.kind = core::LandmarkKind::kPosition;
      lm.position = positions->row(static_cast<Eigen::Index>(i)).transpose();
    }
    out.name = std::to_string(rig.morph_targets.size()) + " shapes -> " + std::to_string(out.target.vertexCount()) +
               " vertices (" + base.name + ", target subdivided twice)";
    return out;
  }();
  return c;
}

void BM_TransferLargeTargetAndWrite(benchmark::State& state) {
  const LargeCase& c = largeCase();
  core::TransferOptions options;
  const core::ScopedThreadCount options_threads(2);
  double transfer = 0, write = 0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    auto r = core::transferRig(c.prepared, c.target, c.target_landmarks, "target", options);
    if (!r) {
      state.SkipWithError(r.error().message.c_str());
      return;
    }
    const auto t1 = std::chrono::steady_clock::now();
    auto glb = core::encodeRigGlb(r->rig);
    if (!glb) {
      state.SkipWithError(glb.error().message.c_str());
      return;
    }
    benchmark::DoNotOptimize(glb->data());
    transfer += std::chrono::duration<double, std::milli>(t1 - t0).count();
    write += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t1).count();
  }
  state.counters["transfer_ms"] = transfer / static_cast<double>(state.iterations());
  state.counters["write_ms"] = write / static_cast<double>(state.iterations());
  state.SetLabel(c.name + ", 2 threads");
}
BENCHMARK(BM_TransferLargeTargetAndWrite)->Unit(benchmark::kMillisecond)->UseRealTime();

// End to end on one thread, as a one-off CLI run does it after reading its
// files: prepare the rig (moved in, as read), transfer, encode the GLB.
void BM_TransferEndToEnd(benchmark::State& state) {
  const Case& c = benchCase();
  core::PrepareOptions prepare;
  const core::ScopedThreadCount prepare_threads(1);
  core::TransferOptions options;
  const core::ScopedThreadCount options_threads(1);
  std::size_t bytes = 0;
  for (auto _ : state) {
    state.PauseTiming();
    core::Rig rig = c.rig;
    state.ResumeTiming();
    auto prepared = core::prepareRig(std::move(rig), c.landmarks, "source", prepare);
    if (!prepared) {
      state.SkipWithError(prepared.error().message.c_str());
      return;
    }
    auto r = core::transferRig(*prepared, c.target, c.target_landmarks, "target", options);
    if (!r) {
      state.SkipWithError(r.error().message.c_str());
      return;
    }
    auto glb = core::encodeRigGlb(r->rig);
    if (!glb) {
      state.SkipWithError(glb.error().message.c_str());
      return;
    }
    bytes = glb->size();
  }
  state.counters["glb_bytes"] = static_cast<double>(bytes);
  state.SetLabel(c.name);
}
BENCHMARK(BM_TransferEndToEnd)->Unit(benchmark::kMillisecond);

void BM_WriteRigGlb(benchmark::State& state) {
  const Case& c = benchCase();
  auto r = core::transferRig(c.prepared, c.target, c.target_landmarks, "target");
  for (auto _ : state) benchmark::DoNotOptimize(core::encodeRigGlb(r->rig));
  state.SetLabel(c.name);
}
BENCHMARK(BM_WriteRigGlb)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
