// The transfer job's body: prepare (or take from a cache) the source rig,
// transfer it to the target, encode the GLB and the diagnostics.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/io/landmarks.h"
#include "core/io/mesh_io.h"
#include "core/jobs/fit_job.h"
#include "core/jobs/job.h"
#include "core/jobs/transfer_options.h"
#include "core/transfer/transfer.h"

namespace core {

// The prepared source rig as a job gets it: prepared for this job, or shared
// from a cache (then no source-only work was done and `read` is null).
struct PreparedRigSource {
  std::shared_ptr<const PreparedRig> rig;
  const MeshReadReport* read = nullptr;  // how the rig file was read, when it was read for this job
  bool cache_hit = false;
};
using PrepareRigSource = std::function<Result<PreparedRigSource>()>;

struct TransferJobInput {
  LoadedMesh target;
  LandmarkSet target_landmarks;        // empty: found by a fit of the rig's face (landmark-free alignment)
  std::string target_label;            // the target's file name, in messages and diagnostics
  TransferSettings settings;
  std::vector<std::string> warnings;   // the caller's, reported with the transfer's
};

struct TransferJobOutput {
  JobOutput output;
  TransferReport report;
  std::optional<FitReport> fit;        // when the job fitted the rig onto the target
};

// `prepare` is called once, timed as the "prepare" stage. The job fits the
// rig's face onto the target (core/fit, stage "fit") for the correspondence
// "fit" and to find the landmarks of a target that has none; `prepare_fit`
// gives the fit reference then (from a cache), or when empty it is prepared
// here from the rig.
Result<TransferJobOutput> runTransferJob(const PrepareRigSource& prepare, TransferJobInput input, const JobRun& run,
                                         const PrepareFitSource& prepare_fit = {});

}  // namespace core
