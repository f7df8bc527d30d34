#include "core/jobs/transfer_job.h"

#include "core/base/parallel.h"
#include "core/io/components_io.h"
#include "core/io/rig_io.h"
#include "core/jobs/diagnostics_json.h"

namespace core {

namespace {

// The landmarks a fit found, as the target's own (positions on it).
LandmarkSet foundLandmarks(const FitReport& report) {
  LandmarkSet out;
  for (const FoundLandmark& found : report.found_landmarks) {
    Landmark l;
    l.name = found.name;
    l.kind = LandmarkKind::kPosition;
    l.position = found.position;
    out.landmarks.push_back(std::move(l));
  }
  return out;
}

// The rig's source fitted onto the target (core/fit), for the correspondence
// "fit" or to find the target's landmarks when it has none. A fit that fails
// its gate fails the job: a transfer through it would carry its faults.
Result<FittedSurface> fitOntoTarget(const PreparedRigSource& source, const PrepareFitSource& prepare_fit,
                                    const TransferJobInput& input, const JobRun& run, double& prepare_ms) {
  const auto t0 = Clock::now();
  std::shared_ptr<const FitReference> reference;
  if (prepare_fit) {
    auto prepared = prepare_fit();
    if (!prepared) return prepared.error();
    reference = prepared->reference;
  } else {
    auto prepared = prepareFitReference(source.rig);
    if (!prepared) return prepared.error();
    reference = std::make_shared<const FitReference>(std::move(*prepared));
  }
  prepare_ms = msSince(t0);
  FitOptions options;  // the scan fit's defaults; searched when the target has no landmarks
  if (run.on_stage) {
    options.on_stage = [&run](std::string_view stage, double fraction) {
      return run.on_stage(stage, 0.1 + 0.4 * fraction);
    };
  }
  auto fitted = fitSurface(*reference, input.target.mesh, input.target_landmarks, input.target_label, options);
  if (!fitted) return fitted.error();
  if (fitted->report.verdict == "fail") {
    std::string reasons;
    for (const std::string& reason : fitted->report.reasons) reasons += (reasons.empty() ? "" : "; ") + reason;
    return makeError(ErrorCode::kQualityGate, input.target_label + ": the fit of the rig onto the target (" +
                                                  (input.target_landmarks.landmarks.empty() ? "to find its landmarks"
                                                                                            : "the correspondence") +
                                                  ") failed its quality gate: " + reasons);
  }
  return fitted;
}

}  // namespace

Result<TransferJobOutput> runTransferJob(const PrepareRigSource& prepare, TransferJobInput input, const JobRun& run,
                                         const PrepareFitSource& prepare_fit) {
  const ScopedThreadCount threads(run.threads);
  // --- prepare (a cache hit skips all source-only work)
  if (!run.stage("prepare", 0.05)) return run.stoppedBefore("prepare");
  auto t0 = Clock::now();
  auto source = prepare();
  if (!source) return source.error();
  const double prepare_ms = msSince(t0);

  // --- fit (the correspondence "fit", or a target without landmarks: the fit finds them)
  TransferSettings& settings = input.settings;
  const bool landmarks_given = !input.target_landmarks.landmarks.empty();
  std::optional<FittedSurface> fitted;
  double fit_prepare_ms = 0.0, fit_ms = 0.0;
  if (settings.correspondence == CorrespondenceMethod::kFit || !landmarks_given) {
    if (!run.stage("fit", 0.1)) return run.stoppedBefore("fit");
    t0 = Clock::now();
    auto fit = fitOntoTarget(*source, prepare_fit, input, run, fit_prepare_ms);
    if (!fit) return fit.error();
    fitted = std::move(*fit);
    fit_ms = msSince(t0) - fit_prepare_ms;
    if (!landmarks_given) input.target_landmarks = foundLandmarks(fitted->report);
  }

  // --- transfer (core reports its own stages; progress 0.1 .. 0.9, after a fit 0.5 .. 0.9)
  const double from = fitted ? 0.5 : 0.1;
  if (run.on_stage) {
    settings.transfer.on_stage = [&run, from](std::string_view stage, double fraction) {
      return run.on_stage(stage, from + (0.9 - from) * fraction);
    };
  }
  auto target = prepareTarget(std::move(input.target.mesh), std::move(input.target_landmarks), input.target_label);
  if (!target) return target.error();
  auto transfer = [&]() -> Result<TransferResult> {
    if (settings.correspondence == CorrespondenceMethod::kWarp) {
      return transferRig(*source->rig, std::move(*target), settings.transfer);
    }
    auto correspondence = correspondThroughFit(source->rig->surface, std::move(*target), fitted->positions,
                                               transferWarpOptions(settings.transfer));
    if (!correspondence) return correspondence.error();
    return transferRig(*source->rig, std::move(*correspondence), settings.transfer);
  };
  auto result = transfer();
  if (!result) return result.error();
  TransferReport& r = result->report;
  for (std::string& warning : input.warnings) r.warnings.push_back(std::move(warning));
  if (!landmarks_given) {
    r.warnings.push_back("the target had no landmarks: the " + std::to_string(fitted->report.found_landmarks.size()) +
                         " used were found by a fit of the rig's face (fit.landmarks.found); check them where the "
                         "eyes or mouth are closed");
  }
  if (fitted) {
    for (const std::string& warning : fitted->report.warnings) r.warnings.push_back("fit: " + warning);
  }

  // --- assemble
  if (!run.stage("write", 0.92)) return run.stoppedBefore("write");
  t0 = Clock::now();
  if (auto ok = applyPresetBake(settings.bake, result->rig, result->components, r.warnings); !ok) {
    return makeError(ok.error().code, input.target_label + ": " + ok.error().message);
  }
  auto glb = encodeRigGlb(result->rig, settings.write);
  if (!glb) return makeError(glb.error().code, run.output_label + ": " + glb.error().message);
  const double write_ms = msSince(t0);

  TransferJobOutput out;
  out.output.glb = std::move(*glb);
  if (result->components) out.output.components = formatComponents(*result->components);
  out.output.cache_hit = source->cache_hit;
  if (source->cache_hit) r.prepare_ms = 0.0;  // the cached preparation was paid by an earlier job
  const double total_prepare_ms = (source->cache_hit ? 0.0 : prepare_ms) + fit_prepare_ms;
  DiagnosticsContext context;
  context.source_read = source->cache_hit ? nullptr : source->read;
  context.target_read = &input.target.report;
  context.extra_timings_ms = {{"read", run.read_ms}, {"write", write_ms}};
  if (fitted) context.extra_timings_ms["fit"] = fit_ms;
  context.total_ms = msSince(run.started);
  context.cache_hit = source->cache_hit;
  context.fit = fitted ? &fitted->report : nullptr;
  context.landmarks_found = !landmarks_given;
  out.output.diagnostics = formatTransferDiagnostics(r, context);
  out.output.timings_ms = {{"read", run.read_ms},
                           {"prepare", total_prepare_ms},
                           {"fit", fit_ms},
                           {"warp", r.warp.warp_ms},
                           {"correspond", r.warp.correspond_ms},
                           {"transfer", r.dense_map_ms + r.weights_ms + r.joints_ms + r.shapes_ms + r.parts_ms + r.attributes_ms +
                                            r.components_ms},
                           {"write", write_ms},
                           {"total", context.total_ms}};
  out.report = std::move(r);
  if (fitted) out.fit = std::move(fitted->report);
  return out;
}

}  // namespace core
