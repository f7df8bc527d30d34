#include "client/local_jobs.h"

#include "core/base/parallel.h"
#include "core/base/timing.h"

#include <chrono>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/spdlog.h>

#include "core/jobs/diagnostics_json.h"
#include "core/io/landmarks.h"
#include "core/jobs/retarget_options.h"
#include "core/jobs/transfer_options.h"
#include "core/io/mesh_io.h"
#include "core/io/rig_io.h"
#include "core/synthetic/synthetic_head.h"
#include "core/synthetic/synthetic_rig.h"
#include "core/retarget/retarget.h"
#include "core/io/trc_io.h"
#include "core/correspond/warp_job.h"
#include "core/jobs/retarget_job.h"
#include "core/jobs/fit_job.h"
#include "core/components/bake.h"
#include "core/components/pose_spec.h"
#include "core/io/components_io.h"
#include "core/jobs/transfer_job.h"

namespace client {

namespace {

using core::Clock;
using core::msSince;

int fail(const core::Error& error) {
  spdlog::error("{} ({})", error.message, core::errorCodeName(error.code));
  return 1;
}

core::Status writeText(const std::filesystem::path& path, const std::string& text) {
  return core::writeFileBytes(path, std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

// Writes the diagnostics file and/or prints them; warns about suspicious
// landmarks and correspondence problems (e.g. region labels).
core::Status emitDiagnostics(const std::string& diagnostics, const std::filesystem::path& file, bool print,
                             const core::WarpReport& warp, const std::vector<std::string>& more_warnings = {}) {
  if (!file.empty()) {
    if (auto ok = writeText(file, diagnostics); !ok) return ok;
  }
  if (print) std::fputs(diagnostics.c_str(), stdout);
  if (!warp.suspicious_landmarks.empty()) {
    spdlog::warn("suspicious landmarks (the others cannot explain them; swapped or misplaced?): {}",
                 core::joinNames(warp.suspicious_landmarks));
  }
  for (const std::string& warning : warp.warnings) spdlog::warn("{}", warning);
  for (const std::string& warning : more_warnings) spdlog::warn("{}", warning);
  return core::Ok{};
}

core::DiagnosticsContext diagnosticsContext(const core::MeshReadReport& source, const core::MeshReadReport& target,
                                            double read_ms, double write_ms, Clock::time_point t_start) {
  core::DiagnosticsContext context;
  context.source_read = &source;
  context.target_read = &target;
  context.extra_timings_ms = {{"read", read_ms}, {"write", write_ms}};
  context.total_ms = msSince(t_start);
  return context;
}

// What the warp and transfer commands read besides the source itself.
struct LandmarkedInputs {
  core::LandmarkSet source_landmarks;
  core::LoadedMesh target;
  core::LandmarkSet target_landmarks;
};

core::Result<LandmarkedInputs> readLandmarkedInputs(const std::filesystem::path& source_landmarks,
                                                    const std::filesystem::path& target,
                                                    const std::filesystem::path& target_landmarks) {
  LandmarkedInputs in;
  auto source_set = core::readLandmarks(source_landmarks);
  if (!source_set) return source_set.error();
  in.source_landmarks = std::move(*source_set);
  auto mesh = core::readMesh(target);
  if (!mesh) return mesh.error();
  in.target = std::move(*mesh);
  if (target_landmarks.empty()) return in;  // a transfer finds them (runTransferJob)
  auto target_set = core::readLandmarks(target_landmarks);
  if (!target_set) return target_set.error();
  in.target_landmarks = std::move(*target_set);
  return in;
}

// The rig's components document (--source-components, --reference-components)
// checked against its face; nullopt when none was given.
core::Result<std::optional<core::ComponentsDocument>> readComponentsOf(const std::filesystem::path& file,
                                                                       const core::Rig& rig) {
  if (file.empty()) return std::optional<core::ComponentsDocument>();
  auto doc = core::readRigComponents(file, rig.mesh);
  if (!doc) return doc.error();
  spdlog::info("read components {} ({} muscles, {} wires, {} clusters, {} controls, {} presets)",
               file.filename().string(), doc->muscles.size(), doc->wires.size(), doc->clusters.size(),
               doc->controls.size(), doc->presets.size());
  return std::optional<core::ComponentsDocument>(std::move(*doc));
}

// The result's components document at --components-out (CLI11 makes it need
// the rig's document, so the job carried one).
core::Status writeComponentsOut(const std::filesystem::path& file, const std::string& components) {
  if (file.empty()) return core::Ok{};
  if (auto ok = writeText(file, components); !ok) return ok;
  spdlog::info("wrote {}", file.string());
  return core::Ok{};
}

}  // namespace

int runWarp(const WarpArgs& args) {
  const auto t_start = Clock::now();
  auto t0 = Clock::now();
  auto source = core::readMesh(args.source);
  if (!source) return fail(source.error());
  auto in = readLandmarkedInputs(args.source_landmarks, args.target, args.target_landmarks);
  if (!in) return fail(in.error());
  const double read_ms = msSince(t0);
  spdlog::info("read source {} ({} vertices), target {} ({} vertices)", args.source.filename().string(),
               source->mesh.vertexCount(), args.target.filename().string(), in->target.mesh.vertexCount());

  const core::ScopedThreadCount threads(args.threads);
  auto prepared = core::prepareSource(source->mesh, in->source_landmarks, args.source.filename().string());
  if (!prepared) return fail(prepared.error());

  core::WarpOptions options = args.plain ? core::plainWarpOptions() : args.light ? core::lightWarpOptions() : core::WarpOptions{};
  if (!args.plain && !args.light) {
    options.refine_iterations = args.refine_iterations;
    options.local_rounds = args.local_rounds;
  }
  options.landmark_tps.regularization = args.landmark_regularization;
  auto result = core::runWarp(*prepared, in->target.mesh, in->target_landmarks, args.target.filename().string(), options);
  if (!result) return fail(result.error());
  result->report.prepare_ms = prepared->prepare_ms;

  t0 = Clock::now();
  core::Mesh guide;
  guide.positions = result->guide.positions;
  guide.triangles = prepared->mesh.triangles;
  guide.regions = prepared->mesh.regions;  // the source's labels, when it has them
  guide.normals = core::computeVertexNormals(guide.positions, guide.triangles);
  if (auto ok = core::writeMeshGlb(guide, args.output); !ok) return fail(ok.error());
  const double write_ms = msSince(t0);

  const core::DiagnosticsContext context = diagnosticsContext(source->report, in->target.report, read_ms, write_ms, t_start);
  const auto& r = result->report;
  if (auto ok = emitDiagnostics(core::formatWarpDiagnostics(r, context), args.diagnostics, args.print_diagnostics, r);
      !ok) {
    return fail(ok.error());
  }
  spdlog::info("warp: {} landmarks, rms residual {:.3g}, suspicious {}; correspondence p95 {:.4g} ({:.3f}% of diagonal), "
               "{} flipped triangles, {} low-confidence target vertices; {:.1f} ms",
               r.landmark_count, r.landmark_rms_residual, r.suspicious_landmarks.size(), r.p95_distance,
               100.0 * r.p95_distance / r.target_diagonal, r.flipped_triangles, r.low_confidence_vertices,
               context.total_ms);
  spdlog::info("wrote {}{}", args.output.string(), args.diagnostics.empty() ? "" : " and " + args.diagnostics.string());
  return 0;
}

int runTransfer(const TransferArgs& args) {
  core::JobRun run;
  run.threads = args.threads;
  run.output_label = args.output.filename().string();
  core::TransferJobInput input;
  if (!args.options.empty()) {
    auto text = core::readFileBytes(args.options);
    if (!text) return fail(text.error());
    auto parsed = core::parseTransferOptions(std::string(text->begin(), text->end()), args.options.filename().string());
    if (!parsed) return fail(parsed.error());
    input.settings = std::move(*parsed);
  }
  if (args.strict) input.settings.transfer.strict = true;

  auto t0 = Clock::now();
  auto source = core::readRig(args.source);
  if (!source) return fail(source.error());
  auto components = readComponentsOf(args.source_components, source->rig);
  if (!components) return fail(components.error());
  auto in = readLandmarkedInputs(args.source_landmarks, args.target, args.target_landmarks);
  if (!in) return fail(in.error());
  run.read_ms = msSince(t0);
  spdlog::info("read rig {} ({} vertices, {} joints, {} shapes, {} animations), target {} ({} vertices)",
               args.source.filename().string(), source->rig.mesh.vertexCount(),
               source->rig.skin ? source->rig.skin->joints.size() : 0, source->rig.morph_targets.size(),
               source->rig.animations.size(), args.target.filename().string(), in->target.mesh.vertexCount());
  input.target = std::move(in->target);
  input.target_landmarks = std::move(in->target_landmarks);
  input.target_label = args.target.filename().string();

  const core::PrepareRigSource prepare = [&]() -> core::Result<core::PreparedRigSource> {
    auto prepared = core::prepareRig(std::move(source->rig), in->source_landmarks, args.source.filename().string());
    if (!prepared) return prepared.error();
    prepared->components = std::move(*components);
    return core::PreparedRigSource{std::make_shared<const core::PreparedRig>(std::move(*prepared)), &source->report, false};
  };
  const std::size_t target_vertices = input.target.mesh.vertexCount();
  auto job = core::runTransferJob(prepare, std::move(input), run);
  if (!job) return fail(job.error());
  if (auto ok = core::writeFileBytes(args.output, job->output.glb); !ok) return fail(ok.error());
  if (auto ok = writeComponentsOut(args.components_out, job->output.components); !ok) return fail(ok.error());

  const auto& r = job->report;
  if (auto ok = emitDiagnostics(job->output.diagnostics, args.diagnostics, args.print_diagnostics, r.warp, r.warnings);
      !ok) {
    return fail(ok.error());
  }
  spdlog::info("transfer: {} joints, {} shapes, {} animations; {} vertices inpainted, {} pruned; "
               "landmark rms {:.3g}, correspondence p95 {:.3f}% of diagonal, {} flipped; {:.1f} ms",
               r.joints, r.shapes, r.animations, r.inpainted_vertices, r.pruned_vertices, r.warp.landmark_rms_residual,
               100.0 * r.warp.p95_distance / r.warp.target_diagonal, r.warp.flipped_triangles,
               job->output.timings_ms.at("total"));
  if (r.uv_seam_vertices > 0) {
    spdlog::info("UVs: {} vertices added where the rig's UV seams cross the target (after its {} own)",
                 r.uv_seam_vertices, target_vertices);
  }
  spdlog::info("wrote {}{}", args.output.string(), args.diagnostics.empty() ? "" : " and " + args.diagnostics.string());
  return 0;
}

int runFit(const FitArgs& args) {
  core::JobRun run;
  run.threads = args.threads;
  run.output_label = args.output.filename().string();
  core::FitJobInput input;
  if (!args.options.empty()) {
    auto text = core::readFileBytes(args.options);
    if (!text) return fail(text.error());
    auto parsed = core::parseFitOptions(std::string(text->begin(), text->end()), args.options.filename().string());
    if (!parsed) return fail(parsed.error());
    input.settings = std::move(*parsed);
  }
  if (args.strict) input.settings.fit.strict = true;

  auto t0 = Clock::now();
  auto reference = core::readRig(args.reference);
  if (!reference) return fail(reference.error());
  auto reference_landmarks = core::readLandmarks(args.reference_landmarks);
  if (!reference_landmarks) return fail(reference_landmarks.error());
  auto components = readComponentsOf(args.reference_components, reference->rig);
  if (!components) return fail(components.error());
  auto scan = core::readMesh(args.scan);
  if (!scan) return fail(scan.error());
  if (!args.scan_landmarks.empty()) {
    auto scan_landmarks = core::readLandmarks(args.scan_landmarks);
    if (!scan_landmarks) return fail(scan_landmarks.error());
    input.scan_landmarks = std::move(*scan_landmarks);
  }
  run.read_ms = msSince(t0);
  spdlog::info("read reference {} ({} vertices, {} shapes), scan {} ({} points, {} triangles)",
               args.reference.filename().string(), reference->rig.mesh.vertexCount(),
               reference->rig.morph_targets.size(), args.scan.filename().string(), scan->mesh.vertexCount(),
               scan->mesh.triangleCount());
  input.scan = std::move(*scan);
  input.scan_label = args.scan.filename().string();

  const core::PrepareFitSource prepare = [&]() -> core::Result<core::PreparedFitSource> {
    const std::string label = args.reference.filename().string();
    auto rig = core::prepareRig(std::move(reference->rig), std::move(*reference_landmarks), label);
    if (!rig) return rig.error();
    rig->components = std::move(*components);
    auto fit_reference = core::prepareFitReference(std::make_shared<const core::PreparedRig>(std::move(*rig)));
    if (!fit_reference) return fit_reference.error();
    return core::PreparedFitSource{std::make_shared<const core::FitReference>(std::move(*fit_reference)),
                                   &reference->report, false};
  };
  auto job = core::runFitJob(prepare, std::move(input), run);
  if (!job) return fail(job.error());
  if (auto ok = emitDiagnostics(job->output.diagnostics, args.diagnostics, args.print_diagnostics, core::WarpReport{},
                                job->report.warnings);
      !ok) {
    return fail(ok.error());
  }
  const core::FitReport& r = job->report;
  spdlog::info("fit: {} ({} alignment, scan in {}, head {:.3f}x the reference); face to scan median {:.3g} / p95 {:.3g} / "
               "max {:.3g} {}, face coverage {:.1f}%, {} flipped; {:.1f} ms",
               r.verdict, r.alignment.method, r.scan.units, r.scan.size_ratio, r.face_distance.median,
               r.face_distance.p95, r.face_distance.max, r.scan.units, 100.0 * r.face_coverage, r.flipped_triangles,
               job->output.timings_ms.at("total"));
  for (const std::string& reason : r.reasons) spdlog::warn("{}", reason);
  if (job->output.refused) return fail(*job->output.refused);
  if (auto ok = core::writeFileBytes(args.output, job->output.glb); !ok) return fail(ok.error());
  if (auto ok = writeComponentsOut(args.components_out, job->output.components); !ok) return fail(ok.error());
  spdlog::info("wrote {}{}", args.output.string(), args.diagnostics.empty() ? "" : " and " + args.diagnostics.string());
  return 0;
}

int runGenerateHead(const GenerateHeadArgs& args) {
  core::HeadShape shape = args.seed == 0 ? core::HeadShape{} : core::randomHeadShape(args.seed, args.variation);
  shape.mouth_open = args.mouth_open;
  core::HeadResolution resolution;
  resolution.columns = args.columns;
  resolution.rows = args.rows;
  resolution.alternate_diagonals = args.alternate_diagonals;
  resolution.jitter = args.jitter;
  resolution.seed = args.seed;
  core::SyntheticHead head = core::generateHead(shape, resolution);
  head.mesh.positions *= args.scale;
  if (auto ok = core::writeMeshGlb(head.mesh, args.output); !ok) return fail(ok.error());
  if (auto ok = writeText(args.landmarks, core::formatLandmarks(head.landmarks)); !ok) return fail(ok.error());
  spdlog::info("wrote {} ({} vertices, {} triangles) and {} ({} landmarks)", args.output.string(),
               head.mesh.vertexCount(), head.mesh.triangleCount(), args.landmarks.string(),
               head.landmarks.landmarks.size());
  return 0;
}

int runRetarget(const RetargetArgs& args) {
  core::JobRun run;
  run.threads = args.threads;
  run.output_label = args.output.filename().string();
  core::RetargetJobInput input;
  core::RetargetSettings& settings = input.settings;
  settings.clip.max_gap_frames = args.max_gap_frames;
  settings.clip.fill_long_gaps = args.fill_long_gaps;
  settings.distances.method = core::parseDistanceMethod(args.method).value_or(core::DistanceMethod::kHybrid);
  core::RetargetOptions& options = settings.retarget;
  options.kernel = core::parseRbfKernel(args.kernel).value_or(core::RbfKernel::kGaussian);
  options.gamma = args.gamma;
  options.rest_frame = args.rest_frame;
  options.remove_head_motion = !args.keep_head_motion;
  options.bake.tolerance = args.tolerance;
  options.bake.exact = args.exact;

  auto t0 = Clock::now();
  auto mesh = core::readMesh(args.mesh);
  if (!mesh) return fail(mesh.error());
  auto markers = core::readLandmarks(args.markers);
  if (!markers) return fail(markers.error());
  auto clip = core::readTrc(args.mocap, settings.clip);
  if (!clip) return fail(clip.error());
  if (!args.stiffness.empty()) {
    auto text = core::readFileBytes(args.stiffness);
    if (!text) return fail(text.error());
    auto stiffness = core::parseStiffness(std::string(text->begin(), text->end()), args.stiffness.filename().string());
    if (!stiffness) return fail(stiffness.error());
    options.stiffness = std::move(*stiffness);
  }
  run.read_ms = msSince(t0);
  spdlog::info("read {} ({} vertices), {} markers, {} ({} markers, {} frames at {} Hz, {})", args.mesh.filename().string(),
               mesh->mesh.vertexCount(), markers->landmarks.size(), args.mocap.filename().string(), clip->markerCount(),
               clip->frameCount(), clip->data_rate, clip->units);
  for (const auto& gap : clip->filled_gaps) {
    spdlog::warn("{}: marker {} missing for {} frames from frame {}: {}", args.mocap.filename().string(), gap.marker,
                 gap.frame_count, gap.first_frame,
                 gap.fill == core::GapFill::kInterpolated ? std::string("interpolated")
                                                          : "carried by its neighbours " + core::joinNames(gap.donors));
  }
  input.mesh = std::move(*mesh);
  input.markers = std::move(*markers);
  input.clip = std::move(*clip);

  auto job = core::runRetargetJob(core::computeMarkerDistancesFor(input, args.mesh.filename().string()),
                                  input, run);
  if (!job) return fail(job.error());
  if (auto ok = core::writeFileBytes(args.output, job->output.glb); !ok) return fail(ok.error());

  const auto& r = job->report;
  if (auto ok = emitDiagnostics(job->output.diagnostics, args.diagnostics, args.print_diagnostics, {}); !ok) {
    return fail(ok.error());
  }
  if (!r.unused_clip_markers.empty()) {
    spdlog::warn("{} clip markers are not in {} and were ignored", r.unused_clip_markers.size(), args.markers.filename().string());
  }
  if (!r.markers_not_in_clip.empty()) {
    spdlog::warn("{} of {} not in {}, not used: {}", r.markers_not_in_clip.size(), args.markers.filename().string(),
                 args.mocap.filename().string(), core::joinNames(r.markers_not_in_clip));
  }
  if (!r.tolerance_met) spdlog::warn("bake tolerance {} not met with the maximum rank {}", r.tolerance, r.rank);
  spdlog::info("retarget ({}, {} kernel): {} frames, {} markers, marker residual max {:.3g}; {} {}, error rms {:.3g} "
               "({:.4f}% of diagonal), relative {:.3g}; head motion {:.1f} deg {}; {:.1f} ms",
               core::distanceMethodName(r.method), core::rbfKernelName(r.kernel), r.frames, r.markers,
               r.marker_max_residual, r.rank, r.exact ? "frame targets" : "modes", r.rms_error,
               100.0 * r.rms_error / r.mesh_diagonal, r.relative_error, r.head_max_rotation_deg,
               r.head_motion_removed ? "removed" : "kept", job->output.timings_ms.at("total"));
  spdlog::info("wrote {}{}", args.output.string(), args.diagnostics.empty() ? "" : " and " + args.diagnostics.string());
  return 0;
}

int runPose(const PoseArgs& args) {
  const auto t_start = Clock::now();
  auto spec = core::readPoseSpec(args.pose);
  if (!spec) return fail(spec.error());
  const std::string pose_label = args.pose.filename().string();
  // Refused before the rig is read; core would refuse too, without naming the flag.
  if (args.components.empty() && (!spec->preset.empty() || !spec->controls.empty())) {
    return fail(core::makeError(core::ErrorCode::kInvalidArgument,
                                pose_label + ": " + (spec->preset.empty() ? "controls" : "preset") +
                                    ": presets and controls need the rig's components document (--components)"));
  }
  auto loaded = core::readRig(args.rig);
  if (!loaded) return fail(loaded.error());
  std::optional<core::ComponentsDocument> components;
  if (!args.components.empty()) {
    auto read = core::readComponents(args.components);
    if (!read) return fail(read.error());
    components = std::move(*read);
  }
  const core::Rig& rig = loaded->rig;
  spdlog::info("read rig {} ({} vertices, {} parts, {} joints, {} shapes)", args.rig.filename().string(),
               rig.mesh.vertexCount(), rig.parts.size(), rig.skin ? rig.skin->joints.size() : 0,
               rig.morph_targets.size());
  if (components) {
    spdlog::info("read components {} ({} controls, {} presets)", args.components.filename().string(),
                 components->controls.size(), components->presets.size());
  }

  const core::PoseLabels labels{pose_label, args.components.filename().string()};
  auto posed = core::poseRig(std::move(loaded->rig), components ? &*components : nullptr, *spec, labels);
  if (!posed) return fail(posed.error());
  const core::PoseReport& r = posed->report;
  for (const std::string& control : r.clamped_controls) spdlog::warn("control '{}' clamped to its range", control);
  if (auto ok = core::writeRigGlb(posed->rig, args.output); !ok) return fail(ok.error());
  spdlog::info("pose{}: {} morph weights, {} joints turned, {} aimed, {} carried by clusters; {} of {} face vertices "
               "moved; {:.1f} ms",
               spec->preset.empty() ? "" : " '" + spec->preset + "'", r.morph_weights.size(), r.joint_rotations.size(),
               r.joint_aims.size(), r.carried_joints.size(), r.moved_face_vertices, posed->rig.mesh.vertexCount(),
               msSince(t_start));
  spdlog::info("wrote {}", args.output.string());
  return 0;
}

int runBake(const BakeArgs& args) {
  const auto t_start = Clock::now();
  auto loaded = core::readRig(args.rig);
  if (!loaded) return fail(loaded.error());
  core::Rig& rig = loaded->rig;
  auto components = readComponentsOf(args.components, rig);
  if (!components) return fail(components.error());
  auto baked = core::bakePresets(rig, **components, args.presets);
  if (!baked) return fail(core::makeError(baked.error().code, args.components.filename().string() + ": " + baked.error().message));
  for (const std::string& warning : baked->warnings) spdlog::warn("{}", warning);
  if (auto ok = core::writeRigGlb(rig, args.output); !ok) return fail(ok.error());
  spdlog::info("baked {} preset{} as morph targets ({} in all); {:.1f} ms", baked->baked.size(),
               baked->baked.size() == 1 ? "" : "s", rig.morph_targets.size(), msSince(t_start));
  spdlog::info("wrote {}", args.output.string());
  return 0;
}

int runDemo(const std::filesystem::path& dir, int threads, bool inputs_only) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return fail(core::makeError(core::ErrorCode::kIo, dir.string() + ": " + ec.message()));
  // The source: a generated rig (skeleton, weights, shapes, one clip).
  const core::SyntheticRig source = core::generateRig();
  const std::filesystem::path source_rig = dir / "source_rig.glb";
  const std::filesystem::path source_landmarks = dir / "source_rig.landmarks.json";
  if (auto ok = core::writeRigGlb(source.rig, source_rig); !ok) return fail(ok.error());
  if (auto ok = writeText(source_landmarks, core::formatLandmarks(source.landmarks)); !ok) return fail(ok.error());
  spdlog::info("wrote {} ({} vertices, {} joints, {} shapes, {} clip)", source_rig.string(), source.rig.mesh.vertexCount(),
               source.rig.skin->joints.size(), source.rig.morph_targets.size(), source.rig.animations.size());
  // The target: another identity, another resolution and triangulation.
  GenerateHeadArgs target;
  target.output = dir / "target_head.glb";
  target.landmarks = dir / "target_head.landmarks.json";
  target.seed = 7;
  target.variation = 0.2;
  target.columns = 90;
  target.rows = 84;
  target.alternate_diagonals = true;
  target.jitter = 0.3;
  target.mouth_open = 0.012;
  if (int rc = runGenerateHead(target)) return rc;
  if (inputs_only) return 0;

  TransferArgs transfer;
  transfer.source = source_rig;
  transfer.source_landmarks = source_landmarks;
  transfer.target = target.output;
  transfer.target_landmarks = target.landmarks;
  transfer.output = dir / "out.glb";
  transfer.diagnostics = dir / "diagnostics.json";
  transfer.threads = threads;
  transfer.print_diagnostics = true;
  return runTransfer(transfer);
}

}  // namespace client
