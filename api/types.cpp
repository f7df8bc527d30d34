#include "api/types.h"

namespace api {

namespace {
constexpr const char* kStatusNames[] = {"queued", "running", "succeeded", "failed", "cancelled"};
constexpr const char* kKindNames[] = {"transfer", "retarget", "fit"};

// The enum value whose name (its index in `names`) is `name`.
template <typename Enum, std::size_t N>
std::optional<Enum> enumNamed(const char* const (&names)[N], std::string_view name) {
  for (std::size_t i = 0; i < N; ++i) {
    if (name == names[i]) return static_cast<Enum>(i);
  }
  return std::nullopt;
}
}  // namespace

const char* jobStatusName(JobStatus status) { return kStatusNames[static_cast<int>(status)]; }

std::optional<JobStatus> parseJobStatus(std::string_view name) { return enumNamed<JobStatus>(kStatusNames, name); }

bool isFinal(JobStatus status) {
  return status == JobStatus::kSucceeded || status == JobStatus::kFailed || status == JobStatus::kCancelled;
}

const char* jobKindName(JobKind kind) { return kKindNames[static_cast<int>(kind)]; }

std::optional<JobKind> parseJobKind(std::string_view name) { return enumNamed<JobKind>(kKindNames, name); }

const std::vector<JobKindInfo>& jobKinds() {
  static const std::vector<JobKindInfo> kinds = {
      {JobKind::kTransfer, true, {"target"}, {"target_landmarks"}},
      {JobKind::kRetarget, false, {"mesh", "markers", "mocap"}, {"stiffness"}},
      {JobKind::kFit, true, {"scan"}, {"scan_landmarks"}},
  };
  return kinds;
}

const JobKindInfo& jobKindInfo(JobKind kind) { return jobKinds()[static_cast<std::size_t>(kind)]; }

}  // namespace api
