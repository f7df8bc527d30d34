// What every job kind's body shares: how it is run (threads, stage hook, the
// clock its total is measured from) and what it delivers (a GLB, the
// diagnostics JSON, stage timings). The CLI's in-process commands and the
// service's workers call the same body (transfer_job.h, retarget_job.h), so
// both give the same bytes by construction; each only reads its inputs (files
// or stored blobs) and writes the outputs where it keeps them.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/base/error.h"
#include "core/base/stage_hook.h"
#include "core/base/timing.h"

namespace core {

struct JobRun {
  int threads = 0;                     // the job's ScopedThreadCount (0 = hardware threads); results do not depend on it
  StageHook on_stage;                  // empty = run to the end
  Clock::time_point started = Clock::now();  // the job's total is measured from here (reading included)
  double read_ms = 0.0;                // the caller's reading of the inputs
  std::string output_label = "result"; // names the GLB in a write error
  std::string job_label;               // prefixes a stop's message ("job 3f2a..."); empty = none

  bool stage(std::string_view name, double progress) const { return !on_stage || on_stage(name, progress); }
  Error stoppedBefore(std::string_view stage) const;
};

struct JobOutput {
  std::vector<std::uint8_t> glb;
  std::string diagnostics;                   // JSON (docs/DIAGNOSTICS.md)
  std::string components;                    // the result's rig components JSON (docs/COMPONENTS.md); empty: none
  std::map<std::string, double> timings_ms;  // per stage and "total", as the service reports them
  bool cache_hit = false;                    // the source-only work came from a cache
  // The job ran but its output failed its gate (a fit's verdict): no GLB, the
  // diagnostics kept all the same, this error (ErrorCode::kQualityGate) naming why.
  std::optional<Error> refused;
};

}  // namespace core
