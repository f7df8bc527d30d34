#include "core/jobs/transfer_job.h"

#include "core/base/parallel.h"
#include "core/io/rig_io.h"
#include "core/jobs/diagnostics_json.h"

namespace core {

Result<TransferJobOutput> runTransferJob(const PrepareRigSource& prepare, TransferJobInput input, const JobRun& run) {
  const ScopedThreadCount threads(run.threads);
  // --- prepare (a cache hit skips all source-only work)
  if (!run.stage("prepare", 0.05)) return run.stoppedBefore("prepare");
  auto t0 = Clock::now();
  auto source = prepare();
  if (!source) return source.error();
  const double prepare_ms = msSince(t0);

  // --- transfer (core reports its own stages; progress 0.1 .. 0.9)
  TransferSettings& settings = input.settings;
  if (run.on_stage) {
    settings.transfer.on_stage = [&run](std::string_view stage, double fraction) {
      return run.on_stage(stage, 0.1 + 0.8 * fraction);
    };
  }
  auto target = prepareTarget(std::move(input.target.mesh), std::move(input.target_landmarks), input.target_label);
  if (!target) return target.error();
  auto result = transferRig(*source->rig, std::move(*target), settings.transfer);
  if (!result) return result.error();
  TransferReport& r = result->report;
  for (std::string& warning : input.warnings) r.warnings.push_back(std::move(warning));

  // --- assemble
  if (!run.stage("write", 0.92)) return run.stoppedBefore("write");
  t0 = Clock::now();
  auto glb = encodeRigGlb(result->rig, settings.write);
  if (!glb) return makeError(glb.error().code, run.output_label + ": " + glb.error().message);
  const double write_ms = msSince(t0);

  TransferJobOutput out;
  out.output.glb = std::move(*glb);
  out.output.cache_hit = source->cache_hit;
  if (source->cache_hit) r.prepare_ms = 0.0;  // the cached preparation was paid by an earlier job
  DiagnosticsContext context;
  context.source_read = source->cache_hit ? nullptr : source->read;
  context.target_read = &input.target.report;
  context.extra_timings_ms = {{"read", run.read_ms}, {"write", write_ms}};
  context.total_ms = msSince(run.started);
  context.cache_hit = source->cache_hit;
  out.output.diagnostics = formatTransferDiagnostics(r, context);
  out.output.timings_ms = {{"read", run.read_ms},
                           {"prepare", source->cache_hit ? 0.0 : prepare_ms},
                           {"warp", r.warp.warp_ms},
                           {"correspond", r.warp.correspond_ms},
                           {"transfer", r.dense_map_ms + r.weights_ms + r.joints_ms + r.shapes_ms + r.attributes_ms},
                           {"write", write_ms},
                           {"total", context.total_ms}};
  out.report = std::move(r);
  return out;
}

}  // namespace core
