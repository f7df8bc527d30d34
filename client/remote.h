// Typed HTTP client of the rigport service (/v1, see api/openapi.json).
// One RemoteClient holds one keep-alive connection (cpp-httplib behind PImpl:
// httplib.h is included by remote.cpp only) and is NOT thread-safe: give each
// thread its own. Every call returns an api::Result carrying the value or an
// api::Problem:
//   - a non-2xx answer: its application/problem+json body (or a Problem made
//     from the status and the body's first bytes when the body is not one);
//   - no answer at all: type urn:rigport:problem:transport, status 0, detail
//     naming the method, URL and httplib's error;
//   - a local file that cannot be read or written: type
//     urn:rigport:problem:client-io, status 0;
//   - a 2xx answer whose body is not the expected JSON: bad-response;
//   - waitJob's own timeout: wait-timeout, status 0.
// Retries: GETs are retried on transport errors (bounded, max_get_retries);
// so is POST /v1/jobs, which always carries an Idempotency-Key (a random one
// when the caller gives none) so a repeat cannot create a second job; a 429
// is retried after its Retry-After (bounded, max_queue_retries). Nothing else
// is retried.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include <nlohmann/json.hpp>

#include "api/types.h"

namespace client {

inline constexpr const char* kTransportProblem = "urn:rigport:problem:transport";
inline constexpr const char* kClientIoProblem = "urn:rigport:problem:client-io";
inline constexpr const char* kBadResponseProblem = "urn:rigport:problem:bad-response";
inline constexpr const char* kWaitTimeoutProblem = "urn:rigport:problem:wait-timeout";

struct Done {};  // the value of calls that return nothing (DELETE)

struct RemoteOptions {
  std::string server_url;                              // "http://host:port" (https:// works too)
  std::string api_key;                                 // sent as "Authorization: Bearer <key>"; empty = none
  // https://: the CA (PEM) that signed the service's certificate; empty =
  // the system's trusted CAs. The certificate is always verified.
  std::filesystem::path ca_certificate_file;
  std::chrono::milliseconds connect_timeout{5'000};    // TCP connect
  std::chrono::milliseconds read_timeout{120'000};     // waiting for each response (uploads are processed before the answer)
  std::chrono::milliseconds write_timeout{120'000};    // sending a request body
  int max_get_retries = 2;                             // extra attempts of a GET after a transport error
  std::chrono::milliseconds get_retry_delay{250};      // before each such retry (doubles each time)
  int max_queue_retries = 5;                           // extra attempts of POST /v1/jobs after 429
  std::chrono::milliseconds max_retry_after{60'000};   // longest single wait honoured for Retry-After
  // No 429 retry wait that would end after this point (default: no limit).
  std::chrono::steady_clock::time_point retry_deadline = std::chrono::steady_clock::time_point::max();
  // Called with the HTTP status of every response received (including the
  // 429s that are retried), or 0 for a transport error. Used by `rigport bench`.
  std::function<void(int status)> on_response;
};

struct RigFiles {
  std::filesystem::path rig;          // GLB
  std::filesystem::path landmarks;    // landmarks JSON
  std::filesystem::path components;   // optional components JSON; empty = none
};

struct UploadedRig {
  api::RigInfo rig;
  bool uploaded = false;              // false: the service already had this content id
};

struct SubmittedJob {
  api::JobInfo job;
  bool created = true;                // false: 200, an earlier job with the same Idempotency-Key
  int queue_retries = 0;              // 429 answers waited out before acceptance
};

struct JobQuery {
  std::string status;                 // "queued", "running", ...; empty = any
  int limit = 0;                      // 0 = the server's default
  std::string after;                  // cursor from JobPage::next
};

// Called after each poll of waitJob with the latest state.
using JobProgressCallback = std::function<void(const api::JobInfo& job)>;

class RemoteClient {
 public:
  explicit RemoteClient(RemoteOptions options);
  ~RemoteClient();
  RemoteClient(const RemoteClient&) = delete;
  RemoteClient& operator=(const RemoteClient&) = delete;

  const RemoteOptions& options() const { return options_; }

  // Computes the content id (api/content_id.h), asks GET /v1/rigs/{id} and
  // uploads (POST /v1/rigs multipart: rig, landmarks, components) only on 404.
  api::Result<UploadedRig> uploadRig(const RigFiles& files);
  api::Result<api::RigInfo> getRig(const std::string& id);
  api::Result<api::RigPage> listRigs();
  api::Result<Done> deleteRig(const std::string& id);

  // POST /v1/jobs: `spec` is sent as is (any kind), `files` maps a multipart
  // field name ("target", "target_landmarks", "mesh", ...) to a local file
  // sent with its file name. Retries 429 after Retry-After (max_queue_retries).
  api::Result<SubmittedJob> submitJob(const nlohmann::json& spec,
                                       const std::map<std::string, std::filesystem::path>& files,
                                       const std::string& idempotency_key = {});
  // `wait` > 0 asks the server to answer when the job finishes or after
  // `wait` (long polling, `wait_ms`), whichever comes first.
  api::Result<api::JobInfo> getJob(const std::string& id,
                                    std::chrono::milliseconds wait = std::chrono::milliseconds(0));
  api::Result<api::JobPage> listJobs(const JobQuery& query = {});
  api::Result<api::JobInfo> cancelJob(const std::string& id);
  api::Result<Done> deleteJob(const std::string& id);  // a final job, its result and the inputs only it used

  // Writes the body of GET /v1/jobs/{id}/result (or /diagnostics, /components)
  // to `path` (through `path`.part, renamed when complete); returns the bytes written.
  api::Result<std::int64_t> downloadResult(const std::string& id, const std::filesystem::path& path);
  api::Result<std::int64_t> downloadDiagnostics(const std::string& id, const std::filesystem::path& path);
  api::Result<std::int64_t> downloadComponents(const std::string& id, const std::filesystem::path& path);
  // The bodies themselves (GLB bytes; diagnostics and components JSON text).
  api::Result<std::string> fetchResult(const std::string& id);
  api::Result<std::string> fetchDiagnostics(const std::string& id);
  api::Result<std::string> fetchComponents(const std::string& id);

  // Polls GET /v1/jobs/{id} until the job is final (succeeded, failed or
  // cancelled) and returns its last state; a failed job is a value, not a
  // problem. With a progress callback it polls every `poll_interval`;
  // without, it long-polls (the server answers when the job finishes) and
  // never asks more often than every `poll_interval`. Gives up with a timeout
  // problem (status 0) after `timeout` (zero = never).
  api::Result<api::JobInfo> waitJob(const std::string& id, const JobProgressCallback& on_progress = {},
                                     std::chrono::milliseconds poll_interval = std::chrono::milliseconds(250),
                                     std::chrono::milliseconds timeout = std::chrono::milliseconds(0));

 private:
  api::Result<Done> deleteAt(const std::string& path);
  api::Result<std::string> fetchJobFile(const std::string& id, const char* file);
  struct Http;
  RemoteOptions options_;
  std::unique_ptr<Http> http_;
};

// Prints "<title> (HTTP <status>): <detail>" (or the transport detail) as one line.
std::string describeProblem(const api::Problem& problem);

}  // namespace client
