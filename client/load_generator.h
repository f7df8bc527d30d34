// `rigport bench`: service-level load. Uploads the rig once to each service
// URL, then `concurrency` threads (each with its own keep-alive RemoteClient,
// client i on URL i mod #URLs: replicas behind no balancer) submit `jobs`
// transfer jobs in total, poll each until final and fetch its result.
// Latency is measured per job from the first submit attempt to the end of the
// result download (429 waits included). Stops when all jobs are done or at
// `timeout_s`. Human-readable lines go to stderr; the LAST stdout line is one
// JSON object (benchSummaryJson).
#pragma once

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace client {

struct BenchArgs {
  std::string server;                 // http://host:port, or several comma-separated (replicas)
  std::string api_key;                // empty = none
  std::string ca_certificate;         // https: CA of the service's certificate; empty = system CAs
  int concurrency = 4;                // client threads
  int jobs = 20;                      // jobs in total
  std::filesystem::path source, source_landmarks, target, target_landmarks;
  std::filesystem::path options;      // transfer options JSON (spec.options); empty = {}
  double timeout_s = 600.0;           // whole-run limit, seconds
  int poll_ms = 20;                   // GET /v1/jobs/{id} interval while waiting
};
int runBench(const BenchArgs& args);

// The service URLs of BenchArgs::server (comma-separated, blanks trimmed,
// empty entries dropped).
std::vector<std::string> benchServers(const std::string& server);

// Linear-interpolated percentile (numpy's default, "type 7") of `sorted`
// (ascending), p in [0, 100]. 0 for an empty vector.
double percentile(const std::vector<double>& sorted, double p);

struct BenchSummary {
  double wall_s = 0.0;                // the whole run (upload excluded), seconds
  double jobs_per_s = 0.0;            // succeeded jobs / wall_s
  std::size_t latency_count = 0;      // jobs with a latency (the succeeded ones)
  double p50_ms = 0.0, p95_ms = 0.0, p99_ms = 0.0, mean_ms = 0.0, max_ms = 0.0;
  int succeeded = 0;
  int failed = 0;                     // final failed/cancelled, or a non-retryable error
  int unfinished = 0;                 // not done when the run stopped (timeout)
  std::map<std::string, int> errors_by_status;  // "429" -> count; "transport" = no response
};

// Pure: the summary of one run from the per-job latencies (any order).
BenchSummary summarizeBench(std::vector<double> latencies_ms, double wall_s, int succeeded, int failed, int unfinished,
                            std::map<std::string, int> errors_by_status);

// {"jobs_per_s":..,"p50_ms":..,"p95_ms":..,"p99_ms":..,"succeeded":..,"failed":..,
//  "errors_by_status":{..}, plus "unfinished","wall_s","mean_ms","max_ms"}; the
// latency keys are null when no job succeeded.
nlohmann::json benchSummaryJson(const BenchSummary& summary);

}  // namespace client
