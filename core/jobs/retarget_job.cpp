#include "core/jobs/retarget_job.h"

#include "core/base/parallel.h"
#include "core/io/rig_io.h"

namespace core {

ComputeMarkerDistances computeMarkerDistancesFor(const RetargetJobInput& input, const std::string& mesh_label) {
  return [&input, mesh_label]() -> Result<MarkerDistancesSource> {
    auto distances = computeMarkerDistances(input.mesh.mesh, input.markers, mesh_label, input.settings.distances);
    if (!distances) return distances.error();
    return MarkerDistancesSource{std::make_shared<const MarkerDistances>(std::move(*distances)), false};
  };
}

Result<RetargetJobOutput> runRetargetJob(const ComputeMarkerDistances& distances, const RetargetJobInput& input,
                                         const JobRun& run) {
  const ScopedThreadCount threads(run.threads);
  // Distance fields depend only on (mesh, markers, distance options): cacheable.
  if (!run.stage("distances", 0.05)) return run.stoppedBefore("distances");
  auto source = distances();
  if (!source) return source.error();

  if (!run.stage("retarget", 0.3)) return run.stoppedBefore("retarget");
  auto result = retargetMocap(input.mesh.mesh, *source->distances, input.clip, input.settings.retarget);
  if (!result) return result.error();
  RetargetReport& r = result->report;
  const double distances_ms = source->cache_hit ? 0.0 : source->distances->compute_ms;
  r.timings_ms["distances"] = distances_ms;
  r.total_ms += distances_ms;

  if (!run.stage("write", 0.9)) return run.stoppedBefore("write");
  auto t0 = Clock::now();
  auto glb = encodeRigGlb(result->rig);
  if (!glb) return makeError(glb.error().code, run.output_label + ": " + glb.error().message);
  const double write_ms = msSince(t0);

  RetargetJobOutput out;
  out.output.glb = std::move(*glb);
  out.output.cache_hit = source->cache_hit;
  const double total_ms = msSince(run.started);
  out.output.diagnostics = formatRetargetDiagnostics(r, {{"read", run.read_ms}, {"write", write_ms}}, total_ms);
  out.output.timings_ms = {{"read", run.read_ms},
                           {"retarget", total_ms - run.read_ms - write_ms},
                           {"write", write_ms},
                           {"total", total_ms}};
  out.report = std::move(r);
  return out;
}

}  // namespace core
