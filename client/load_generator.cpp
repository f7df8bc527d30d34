#include "client/load_generator.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <mutex>
#include <numeric>
#include <optional>
#include <thread>

#include <spdlog/spdlog.h>

#include "api/json.h"
#include "client/remote.h"

namespace client {

double percentile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  const double rank = std::clamp(p, 0.0, 100.0) / 100.0 * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(rank));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (rank - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

BenchSummary summarizeBench(std::vector<double> latencies_ms, double wall_s, int succeeded, int failed, int unfinished,
                            std::map<std::string, int> errors_by_status) {
  BenchSummary s;
  std::sort(latencies_ms.begin(), latencies_ms.end());
  s.wall_s = wall_s;
  s.jobs_per_s = wall_s > 0.0 ? succeeded / wall_s : 0.0;
  s.latency_count = latencies_ms.size();
  if (!latencies_ms.empty()) {
    s.p50_ms = percentile(latencies_ms, 50.0);
    s.p95_ms = percentile(latencies_ms, 95.0);
    s.p99_ms = percentile(latencies_ms, 99.0);
    s.mean_ms = std::accumulate(latencies_ms.begin(), latencies_ms.end(), 0.0) / static_cast<double>(latencies_ms.size());
    s.max_ms = latencies_ms.back();
  }
  s.succeeded = succeeded;
  s.failed = failed;
  s.unfinished = unfinished;
  s.errors_by_status = std::move(errors_by_status);
  return s;
}

nlohmann::json benchSummaryJson(const BenchSummary& s) {
  const auto latency = [&](double ms) { return s.latency_count ? nlohmann::json(ms) : nlohmann::json(nullptr); };
  nlohmann::json errors = nlohmann::json::object();
  for (const auto& [status, count] : s.errors_by_status) errors[status] = count;
  return {{"jobs_per_s", s.jobs_per_s}, {"p50_ms", latency(s.p50_ms)}, {"p95_ms", latency(s.p95_ms)},
          {"p99_ms", latency(s.p99_ms)}, {"succeeded", s.succeeded}, {"failed", s.failed},
          {"errors_by_status", errors}, {"unfinished", s.unfinished}, {"wall_s", s.wall_s},
          {"mean_ms", latency(s.mean_ms)}, {"max_ms", latency(s.max_ms)}};
}

namespace {

using Clock = std::chrono::steady_clock;

// What one client thread saw; merged after the run.
struct WorkerTally {
  std::vector<double> latencies_ms;
  int succeeded = 0, failed = 0, unfinished = 0;
  std::map<std::string, int> errors_by_status;
};

struct SharedRun {
  const BenchArgs* args = nullptr;
  nlohmann::json spec;
  std::map<std::string, std::filesystem::path> files;
  Clock::time_point deadline;
  std::atomic<int> done{0}, ok{0}, bad{0};
  std::mutex log_mutex;
  int problems_logged = 0;  // the first few problems are logged in full
};

void logProblem(SharedRun& run, const std::string& what, const api::Problem& problem) {
  std::lock_guard<std::mutex> lock(run.log_mutex);
  if (run.problems_logged++ < 5) spdlog::warn("bench: {}: {}", what, describeProblem(problem));
}

// Each client runs its own share of the jobs (not a shared counter), so the
// jobs spread over several services as the clients do, whichever is faster.
void runWorker(SharedRun& run, WorkerTally& tally, const std::string& server, int jobs) {
  RemoteOptions options;
  options.server_url = server;
  options.api_key = run.args->api_key;
  options.ca_certificate_file = run.args->ca_certificate;
  options.max_queue_retries = 1'000'000;  // bounded by retry_deadline instead
  options.retry_deadline = run.deadline;
  options.on_response = [&tally](int status) {
    if (status < 200 || status >= 300) ++tally.errors_by_status[status == 0 ? "transport" : std::to_string(status)];
  };
  RemoteClient client(options);
  const auto poll = std::chrono::milliseconds(std::max(1, run.args->poll_ms));
  for (int job = 0; job < jobs; ++job) {
    if (Clock::now() >= run.deadline) return;
    const auto t0 = Clock::now();
    bool succeeded = false;
    bool timed_out = false;
    auto submitted = client.submitJob(run.spec, run.files);
    if (!submitted) {
      // 429 comes back only when waiting longer would pass the deadline.
      timed_out = submitted.error().status == 429;
      if (!timed_out) logProblem(run, "submit", submitted.error());
    } else {
      const std::string id = submitted->job.id;
      const auto remaining = std::chrono::duration_cast<std::chrono::milliseconds>(run.deadline - Clock::now());
      auto final_job = client.waitJob(id, {}, poll, std::max(remaining, std::chrono::milliseconds(1)));
      if (!final_job) {
        timed_out = final_job.error().type == kWaitTimeoutProblem;
        if (!timed_out) logProblem(run, "wait " + id, final_job.error());
      } else if (final_job->status != api::JobStatus::kSucceeded) {
        if (final_job->error) logProblem(run, "job " + id + " " + api::jobStatusName(final_job->status), *final_job->error);
      } else if (auto result = client.fetchResult(id); !result) {
        logProblem(run, "result " + id, result.error());
      } else {
        succeeded = true;
        tally.latencies_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      }
    }
    if (succeeded) {
      ++tally.succeeded;
      ++run.ok;
    } else if (timed_out) {
      ++tally.unfinished;
    } else {
      ++tally.failed;
      ++run.bad;
    }
    ++run.done;
  }
}

}  // namespace

std::vector<std::string> benchServers(const std::string& server) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= server.size()) {
    const std::size_t comma = std::min(server.find(',', start), server.size());
    std::string url = server.substr(start, comma - start);
    url.erase(0, url.find_first_not_of(" \t"));
    url.erase(url.find_last_not_of(" \t") + 1);
    if (!url.empty()) out.push_back(std::move(url));
    start = comma + 1;
  }
  return out;
}

int runBench(const BenchArgs& args) {
  if (args.concurrency < 1 || args.jobs < 1) {
    spdlog::error("bench: --concurrency and --jobs must be at least 1");
    return 2;
  }
  nlohmann::json options = nlohmann::json::object();
  if (!args.options.empty()) {
    std::ifstream in(args.options, std::ios::binary);
    if (!in) {
      spdlog::error("bench: cannot read {}", args.options.string());
      return 1;
    }
    auto parsed = api::parseJsonText(std::string(std::istreambuf_iterator<char>(in), {}), args.options.string());
    if (!parsed || !parsed->is_object()) {
      spdlog::error("bench: {}", !parsed ? parsed.error() : args.options.string() + ": expected a JSON object");
      return 1;
    }
    options = std::move(*parsed);
  }

  const std::vector<std::string> servers = benchServers(args.server);
  if (servers.empty()) {
    spdlog::error("bench: --server names no service URL");
    return 2;
  }
  // The rig on every service (its id is its content hash: the same on each).
  std::optional<UploadedRig> rig;
  for (const std::string& server : servers) {
    RemoteOptions upload_options;
    upload_options.server_url = server;
    upload_options.api_key = args.api_key;
    upload_options.ca_certificate_file = args.ca_certificate;
    RemoteClient uploader(upload_options);
    auto uploaded = uploader.uploadRig({args.source, args.source_landmarks, {}});
    if (!uploaded) {
      spdlog::error("bench: rig upload to {}: {}", server, describeProblem(uploaded.error()));
      return 1;
    }
    spdlog::info("bench: rig {} {} {}", uploaded->rig.id, uploaded->uploaded ? "uploaded to" : "already on", server);
    rig = std::move(*uploaded);
  }

  SharedRun run;
  run.args = &args;
  run.spec = {{"kind", "transfer"}, {"rig", rig->rig.id}, {"options", options}};
  run.files = {{"target", args.target}, {"target_landmarks", args.target_landmarks}};
  const auto start = Clock::now();
  run.deadline = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(args.timeout_s));
  spdlog::info("bench: {} jobs, {} client threads, against {}", args.jobs, args.concurrency, args.server);

  std::vector<WorkerTally> tallies(static_cast<std::size_t>(args.concurrency));
  std::vector<std::thread> threads;
  threads.reserve(tallies.size());
  for (std::size_t i = 0; i < tallies.size(); ++i) {
    const int share = args.jobs / args.concurrency + (static_cast<int>(i) < args.jobs % args.concurrency ? 1 : 0);
    threads.emplace_back([&run, &tally = tallies[i], &server = servers[i % servers.size()], share] {
      runWorker(run, tally, server, share);
    });
  }

  // Progress once a second until every worker has stopped.
  std::atomic<bool> finished{false};
  std::thread reporter([&] {
    auto last = Clock::now();
    while (!finished.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (Clock::now() - last < std::chrono::seconds(1)) continue;
      last = Clock::now();
      spdlog::info("bench: {}/{} done ({} ok, {} failed), {:.1f} s", run.done.load(), args.jobs, run.ok.load(),
                   run.bad.load(), std::chrono::duration<double>(Clock::now() - start).count());
    }
  });
  for (auto& t : threads) t.join();
  const double wall_s = std::chrono::duration<double>(Clock::now() - start).count();
  finished = true;
  reporter.join();

  std::vector<double> latencies;
  int succeeded = 0, failed = 0, unfinished = 0;
  std::map<std::string, int> errors;
  for (const auto& t : tallies) {
    latencies.insert(latencies.end(), t.latencies_ms.begin(), t.latencies_ms.end());
    succeeded += t.succeeded;
    failed += t.failed;
    unfinished += t.unfinished;
    for (const auto& [status, count] : t.errors_by_status) errors[status] += count;
  }
  unfinished += std::max(0, args.jobs - (succeeded + failed + unfinished));  // never started (timeout)
  const BenchSummary s = summarizeBench(std::move(latencies), wall_s, succeeded, failed, unfinished, errors);

  spdlog::info("bench: {} succeeded, {} failed, {} unfinished in {:.2f} s: {:.2f} jobs/s", s.succeeded, s.failed,
               s.unfinished, s.wall_s, s.jobs_per_s);
  if (s.latency_count > 0) {
    spdlog::info("bench: latency submit->result p50 {:.1f} ms, p95 {:.1f} ms, p99 {:.1f} ms, max {:.1f} ms", s.p50_ms,
                 s.p95_ms, s.p99_ms, s.max_ms);
  }
  for (const auto& [status, count] : s.errors_by_status) spdlog::info("bench: HTTP {}: {} responses", status, count);
  std::printf("%s\n", benchSummaryJson(s).dump().c_str());
  std::fflush(stdout);
  return s.failed == 0 && s.unfinished == 0 ? 0 : 1;
}

}  // namespace client
