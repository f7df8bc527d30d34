// The wire types of the REST contract (/v1), shared by server/ and client/:
// plain structs; JSON at this edge only (api/json.h), validation in
// api/validate.h. The OpenAPI document api/openapi.json describes exactly
// these shapes. api/ never includes core/.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/result.h"

namespace api {

enum class JobStatus { kQueued, kRunning, kSucceeded, kFailed, kCancelled };
const char* jobStatusName(JobStatus status);            // "queued", "running", ...
std::optional<JobStatus> parseJobStatus(std::string_view name);
bool isFinal(JobStatus status);                          // succeeded, failed or cancelled

enum class JobKind { kTransfer, kRetarget, kFit };
const char* jobKindName(JobKind kind);                   // "transfer", "retarget": the spec's "kind"
std::optional<JobKind> parseJobKind(std::string_view name);

// RFC 9457 problem details (application/problem+json). `type` is a stable URI
// per problem class (problemType()); `detail` names the field or file at fault.
struct Problem {
  std::string type;
  std::string title;
  int status = 500;
  std::string detail;
  std::string instance;        // request path, or the job id for job errors
};

// A value or the problem that prevented it (server checks, client calls).
template <typename T>
using Result = rigport::Result<T, Problem>;


struct RigInfo {
  std::string id;              // content hash of rig + landmarks + components (hex sha256)
  std::string name;            // uploaded file name
  std::int64_t size_bytes = 0; // rig file bytes
  int vertices = 0;
  int joints = 0;
  int morph_targets = 0;
  int landmarks = 0;
  bool has_components = false;
  std::string created_at;      // RFC 3339 UTC
  // The _REGION labels its mesh carries, ascending (empty: none); absent for
  // rigs stored before the service recorded them.
  std::optional<std::vector<int>> region_labels;
};

// The `spec` part of POST /v1/jobs: {"kind":"transfer","rig":"<id>","options":{...}}.
struct JobSpec {
  JobKind kind = JobKind::kTransfer;
  std::string rig;             // rig id (transfer)
  nlohmann::json options = nlohmann::json::object();  // kind-specific, validated by the kind's parser
};

struct JobInfo {
  std::string id;
  std::string kind;            // jobKindName; text, so a client reads listings of kinds newer than itself
  std::string rig;
  JobStatus status = JobStatus::kQueued;
  std::string stage;           // current or last pipeline stage ("queued", "prepare", "warp", ..., "done")
  double progress = 0.0;       // 0..1
  int attempts = 0;            // runs started (> 1 after a restart requeued it)
  bool cache_hit = false;      // the prepared rig came from the cache
  bool has_components = false; // succeeded with a rig components document (GET /v1/jobs/{id}/components)
  std::string created_at, started_at, finished_at;  // RFC 3339 UTC, empty when not yet
  std::map<std::string, double> timings_ms;          // per stage, when finished
  std::map<std::string, std::string> files;          // the uploaded files' names, by field ("target": "actor_07.glb")
  std::optional<Problem> error;                      // when failed or cancelled
};

// GET /v1/jobs and GET /v1/rigs pages: {"items":[...], "next":"<cursor>"|null}.
struct JobPage {
  std::vector<JobInfo> items;
  std::string next;            // cursor for ?after=; empty = last page
};
struct RigPage {
  std::vector<RigInfo> items;
};

// What a job kind needs: a rig or not, and the multipart file fields besides
// `spec` (required first, then optional).
struct JobKindInfo {
  JobKind kind;
  bool needs_rig = false;
  std::vector<std::string> required_files;
  std::vector<std::string> optional_files;
};
const std::vector<JobKindInfo>& jobKinds();  // every kind the service runs
const JobKindInfo& jobKindInfo(JobKind kind);

}  // namespace api
