#include "core/jobs/job.h"

namespace core {

Error JobRun::stoppedBefore(std::string_view stage) const {
  return makeError(ErrorCode::kCancelled, (job_label.empty() ? "" : job_label + ": ") + "stopped before " + std::string(stage));
}

}  // namespace core
