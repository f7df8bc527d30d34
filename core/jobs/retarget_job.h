// The retarget job's body: marker distances (computed, or taken from a
// cache), the RBF retarget of the clip, the GLB and the diagnostics.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/io/trc_io.h"
#include "core/jobs/job.h"
#include "core/jobs/retarget_options.h"
#include "core/retarget/retarget.h"

namespace core {

struct MarkerDistancesSource {
  std::shared_ptr<const MarkerDistances> distances;
  bool cache_hit = false;
};
using ComputeMarkerDistances = std::function<Result<MarkerDistancesSource>()>;

struct RetargetJobInput {
  LoadedMesh mesh;
  LandmarkSet markers;
  MarkerTrajectories clip;
  RetargetSettings settings;           // its stiffness filled in by the caller
};

struct RetargetJobOutput {
  JobOutput output;
  RetargetReport report;
};

// `distances` is called once, as the "distances" stage; computeMarkerDistancesFor
// gives the uncached one.
Result<RetargetJobOutput> runRetargetJob(const ComputeMarkerDistances& distances, const RetargetJobInput& input,
                                         const JobRun& run);
ComputeMarkerDistances computeMarkerDistancesFor(const RetargetJobInput& input, const std::string& mesh_label);

}  // namespace core
