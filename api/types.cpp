#include "api/types.h"

namespace api {

namespace {
constexpr const char* kStatusNames[] = {"queued", "running", "succeeded", "failed", "cancelled"};
}  // namespace

const char* jobStatusName(JobStatus status) { return kStatusNames[static_cast<int>(status)]; }

std::optional<JobStatus> parseJobStatus(std::string_view name) {
  for (int i = 0; i < 5; ++i) {
    if (name == kStatusNames[i]) return static_cast<JobStatus>(i);
  }
  return std::nullopt;
}

bool isFinal(JobStatus status) {
  return status == JobStatus::kSucceeded || status == JobStatus::kFailed || status == JobStatus::kCancelled;
}

}  // namespace api

namespace api {

const std::vector<JobKind>& jobKinds() {
  static const std::vector<JobKind> kinds = {
      {"transfer", true, {"target", "target_landmarks"}, {}},
      {"retarget", false, {"mesh", "markers", "mocap"}, {"stiffness"}},
  };
  return kinds;
}

const JobKind* findJobKind(std::string_view name) {
  for (const auto& k : jobKinds()) {
    if (k.name == name) return &k;
  }
  return nullptr;
}

}  // namespace api
