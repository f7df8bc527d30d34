// Jobs: a bounded in-memory queue of accepted job ids in front of a worker
// pool. The store is the truth (a job is accepted once its row is committed);
// the queue only orders work. Workers run one job each (core work never runs
// on an HTTP thread), report stage and progress, honour cancellation and the
// per-job time limit at stage boundaries, and write results to the store
// before the job is marked finished.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <shared_mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "api/types.h"
#include "server/config.h"
#include "server/convert.h"
#include "server/json_log.h"
#include "server/metrics.h"
#include "server/prepared_cache.h"
#include "server/storage_health.h"
#include "server/store.h"
#include "server/timestamps.h"

namespace server {

struct LiveProgress {
  std::string stage;
  double progress = 0.0;
  bool cancel_requested = false;
};

class JobManager {
 public:
  // Workers hold `blob_collection` shared from writing a result blob until the
  // row references it (see server/retention.h).
  // Storage faults (a failed store or blob read or write) are reported to
  // `storage`; the job goes back to the front of the queue, and no job starts
  // until storage takes writes again (it fails only when its own data keeps
  // failing, config.storage_retries_per_job times).
  JobManager(MetadataStore& store, BlobStore& blobs, std::shared_mutex& blob_collection, StorageHealth& storage,
             Caches& caches, Metrics& metrics, const ServerConfig& config, JsonLog log);
  ~JobManager();  // stop(0): workers abandon nothing durable, queued/running rows stay for the next start
  JobManager(const JobManager&) = delete;
  JobManager& operator=(const JobManager&) = delete;

  // Recovery (running -> queued, every unfinished job queued in submission
  // order) and the worker threads.
  void start();

  // Commits the job (or finds the earlier one with its Idempotency-Key) and
  // queues it. A full queue is a 429 problem; nothing is stored then.
  api::Result<std::pair<JobRecord, bool>> submit(const JobRecord& job);

  // Queued: cancelled now. Running: stops at its next stage boundary. Final: 409.
  api::Result<JobRecord> cancel(const std::string& tenant, const std::string& id);

  // Stage and progress of a running job (the store has the rest).
  std::optional<LiveProgress> live(const std::string& id) const;
  int queueDepth() const;
  int runningJobs() const;

  // Long-polling GET: blocks until the job is neither queued nor running
  // here (its final state is in the store), the server stops, or `max_wait`
  // passes. At most `max_waiters` requests wait at once (each holds an HTTP
  // thread); the others return at once. Returns false when it did not wait.
  bool waitUntilSettled(const std::string& id, std::chrono::milliseconds max_wait, int max_waiters);

  // Graceful stop: no new jobs start; running ones get `grace_s` to finish.
  // Returns true when every running job finished in time (the others stay
  // `running` in the store and are requeued at the next start).
  bool stop(double grace_s);

 private:
  struct Running {
    std::string stage = "queued";
    double progress = 0.0;
    std::atomic<bool> cancel{false};
  };
  // What becomes of a job its worker gives back: nothing more (final, or
  // gone), or run again once storage recovers, its row still queued or left
  // running (requeued in the store first).
  enum class Retry { kNo, kQueued, kRunning };
  struct Execution {
    core::Result<core::JobOutput> outcome = core::Error{core::ErrorCode::kCancelled, "not run"};
    std::string stage;       // the last stage reached
    bool timed_out = false;
  };
  void workerLoop();
  Retry runOne(const std::string& tenant, const std::string& id, bool requeue_first);
  Execution execute(const JobRecord& job, Running& state);  // the job body with stage, cancel and time-limit hooks
  void recordFailure(JobRecord& job, const core::Error& error, const Execution& run) const;
  Retry storageFault(const std::string& tenant, const std::string& id, const std::string& where, const std::string& detail,
                     Retry retry);

  MetadataStore& store_;
  BlobStore& blobs_;
  std::shared_mutex& blob_collection_;
  StorageHealth& storage_;
  Caches& caches_;
  Metrics& metrics_;
  const ServerConfig config_;
  JsonLog log_;

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::condition_variable settled_;                          // a job left the queue or finished running
  int waiters_ = 0;                                          // requests in waitUntilSettled
  std::deque<std::pair<std::string, std::string>> queue_;   // (tenant, id)
  int reserved_ = 0;                                         // submissions between capacity check and commit
  std::map<std::string, std::shared_ptr<Running>> running_;  // by job id
  std::set<std::string> requeue_first_;                      // queued here, left running in the store
  std::map<std::string, int> storage_faults_;                // storage faults per job since its last finish
  bool stopping_ = false;
  bool abandoning_ = false;                                  // stop() past its grace period
  std::vector<std::thread> workers_;
};

// The wire view of a stored job (with live stage/progress when running).
api::JobInfo jobInfoOf(const JobRecord& job, const std::optional<LiveProgress>& live);

}  // namespace server
