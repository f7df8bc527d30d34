#include "core/jobs/fit_job.h"

#include "core/base/parallel.h"
#include "core/io/components_io.h"
#include "core/io/rig_io.h"
#include "core/jobs/diagnostics_json.h"

namespace core {

Result<FitJobOutput> runFitJob(const PrepareFitSource& prepare, FitJobInput input, const JobRun& run) {
  const ScopedThreadCount threads(run.threads);
  if (!run.stage("prepare", 0.05)) return run.stoppedBefore("prepare");
  auto t0 = Clock::now();
  auto source = prepare();
  if (!source) return source.error();
  const double prepare_ms = source->cache_hit ? 0.0 : msSince(t0);

  FitSettings& settings = input.settings;
  if (run.on_stage) {
    settings.fit.on_stage = [&run](std::string_view stage, double fraction) {
      return run.on_stage(stage, 0.1 + 0.8 * fraction);
    };
  }
  auto result = fitScan(*source->reference, input.scan.mesh, input.scan_landmarks, input.scan_label, settings.fit);
  if (!result) return result.error();
  FitReport& r = result->report;
  for (std::string& warning : input.warnings) r.warnings.push_back(std::move(warning));

  FitJobOutput out;
  const bool refused = r.verdict == "fail" || (r.verdict == "warn" && settings.fit.strict);
  double write_ms = 0.0;
  if (refused) {
    std::string reasons;
    for (const std::string& reason : r.reasons) reasons += (reasons.empty() ? "" : "; ") + reason;
    out.output.refused = Error{ErrorCode::kQualityGate, input.scan_label + ": the fit " +
                                                     (r.verdict == "fail" ? "failed its quality gate"
                                                                          : "drew warnings from its quality gate (strict)") +
                                                     ": " + reasons};
  } else {
    if (!run.stage("write", 0.92)) return run.stoppedBefore("write");
    t0 = Clock::now();
    if (auto ok = applyPresetBake(settings.bake, result->rig, result->components, r.warnings); !ok) {
      return makeError(ok.error().code, input.scan_label + ": " + ok.error().message);
    }
    auto glb = encodeRigGlb(result->rig, settings.write);
    if (!glb) return makeError(glb.error().code, run.output_label + ": " + glb.error().message);
    out.output.glb = std::move(*glb);
    if (result->components) out.output.components = formatComponents(*result->components);
    write_ms = msSince(t0);
  }
  out.output.cache_hit = source->cache_hit;
  DiagnosticsContext context;
  context.target_read = &input.scan.report;
  context.extra_timings_ms = {{"read", run.read_ms}, {"prepare", prepare_ms}, {"write", write_ms}};
  context.total_ms = msSince(run.started);
  context.cache_hit = source->cache_hit;
  out.output.diagnostics = formatFitDiagnostics(r, context);
  out.output.timings_ms = {{"read", run.read_ms},  {"prepare", prepare_ms}, {"scan", r.scan_ms},
                           {"align", r.align_ms},  {"fit", r.fit_ms},       {"gate", r.gate_ms},
                           {"rebuild", r.rebuild_ms}, {"write", write_ms},  {"total", context.total_ms}};
  out.report = std::move(r);
  return out;
}

}  // namespace core
