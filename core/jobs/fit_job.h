// The fit job's body: prepare (or take from a cache) the reference, fit it to
// the scan, rebuild the rig, encode the GLB and the diagnostics.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/fit/fit.h"
#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/jobs/fit_options.h"
#include "core/jobs/job.h"

namespace core {

// The prepared reference as a job gets it: prepared for this job, or shared
// from a cache (then no reference-only work was done and `read` is null).
struct PreparedFitSource {
  std::shared_ptr<const FitReference> reference;
  const MeshReadReport* read = nullptr;
  bool cache_hit = false;
};
using PrepareFitSource = std::function<Result<PreparedFitSource>()>;

struct FitJobInput {
  LoadedMesh scan;
  LandmarkSet scan_landmarks;          // empty: the alignment searches
  std::string scan_label;              // the scan's file name, in messages and diagnostics
  FitSettings settings;
  std::vector<std::string> warnings;   // the caller's, reported with the fit's
};

struct FitJobOutput {
  // glb empty and `refused` set when the gate refused the fit (verdict fail,
  // or warn with strict); the diagnostics are written all the same.
  JobOutput output;
  FitReport report;
};

// `prepare` is called once, timed as the "prepare" stage.
Result<FitJobOutput> runFitJob(const PrepareFitSource& prepare, FitJobInput input, const JobRun& run);

}  // namespace core
