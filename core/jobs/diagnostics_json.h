// Diagnostics JSON of the assemble stage: stable key names, documented in
// docs/DIAGNOSTICS.md (and later in the API spec). nlohmann::json is used
// privately in the .cpp only.
#pragma once

#include <map>
#include <string>

#include "core/io/mesh_io.h"
#include "core/transfer/transfer.h"
#include "core/correspond/warp_job.h"
#include "core/fit/fit.h"

namespace core {

struct DiagnosticsContext {
  const MeshReadReport* source_read = nullptr;  // how the source file was read, if from a file
  const MeshReadReport* target_read = nullptr;  // how the target file was read, if from a file
  std::map<std::string, double> extra_timings_ms;  // e.g. "read", "write" measured by the caller
  double total_ms = -1.0;                          // overrides report.total_ms when >= 0
  bool cache_hit = false;                          // the prepared source came from a cache
  // A transfer's fit of the rig onto the target (correspondence "fit", or to
  // find its landmarks): reported under "fit" as formatFitDiagnostics has it.
  const FitReport* fit = nullptr;
  bool landmarks_found = false;                    // the target's landmarks were found by that fit
};

// Pretty-printed JSON (2-space indent), keys in a fixed order.
std::string formatWarpDiagnostics(const WarpReport& report, const DiagnosticsContext& context = {});

// The warp keys plus weights/shapes/joints/animations and the transfer stages'
// timings (prepare, warp, correspond, dense_map, weights, joints, shapes,
// animations, attributes, write, total), lined up with the papers' Tables 5.1-5.2.
std::string formatTransferDiagnostics(const TransferReport& report, const DiagnosticsContext& context = {});

// The fit's report (docs/DIAGNOSTICS.md "Fit"): scan, alignment, landmarks,
// stages, distances, coverage, folds, rebuild, verdict and the stages'
// timings (read, prepare, scan, align, fit, gate, rebuild, write, total).
// `context.target_read` is the scan's read report.
std::string formatFitDiagnostics(const FitReport& report, const DiagnosticsContext& context = {});

}  // namespace core
