// Jobs: the queue lives in the store, a worker pool here. A job is accepted
// once its row is committed; a worker claims the oldest queued job under a
// lease (MetadataStore::claimNextJob: on PostgreSQL, FOR UPDATE SKIP LOCKED,
// so replicas sharing the database never claim one job twice), renewed by a
// heartbeat while it runs. A replica that dies leaves its jobs to expire and
// be requeued by any live one; the attempt counter fences every state change
// and result write, so a worker that lost its lease cannot overwrite the new
// owner's result. Workers run one job each (core work never runs on an HTTP
// thread), report stage and progress (the heartbeat stores them for other
// replicas), honour cancellation (asked on any replica) and the per-job time
// limit at stage boundaries, and write results to the store before the job
// is marked finished.
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

#include "server/blob_collection.h"
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
  // `storage`; the job goes back to the queue (at its place: the oldest
  // first), and no job starts here until storage takes writes again (it fails
  // only when its own data keeps failing, config.storage_retries_per_job times).
  JobManager(MetadataStore& store, BlobStore& blobs, BlobCollection& blob_collection, StorageHealth& storage,
             Caches& caches, Metrics& metrics, const ServerConfig& config, JsonLog log);
  ~JobManager();  // stop(0): workers abandon nothing durable, queued/running rows stay for the next start
  JobManager(const JobManager&) = delete;
  JobManager& operator=(const JobManager&) = delete;

  // Recovery on the embedded store (its one process: every running job back
  // to queued), the workers and the lease keeper (heartbeats, expired leases).
  void start();

  // Commits the job (or finds the earlier one with its Idempotency-Key) and
  // wakes a worker. A full queue (queued jobs of every replica) is a 429
  // problem; nothing is stored then.
  api::Result<std::pair<JobRecord, bool>> submit(const JobRecord& job);

  // Queued: cancelled now. Running (here or on another replica): stops at its
  // next stage boundary after its owner sees the request. Final: 409.
  api::Result<JobRecord> cancel(const std::string& tenant, const std::string& id);

  // Stage and progress of a job running here (the store has the rest, with
  // the progress of other replicas' jobs as of their last heartbeat).
  std::optional<LiveProgress> live(const std::string& id) const;
  int queueDepth();        // queued jobs in the store (all replicas)
  int runningJobs() const; // on this replica's workers
  // The name this replica's leases carry.
  const std::string& owner() const { return owner_; }

  // Long-polling GET: blocks until the job is final in the store, the server
  // stops, or `max_wait` passes. At most `max_waiters` requests wait at once
  // (each holds an HTTP thread); the others return at once. Returns false
  // when it did not wait.
  bool waitUntilSettled(const std::string& tenant, const std::string& id, std::chrono::milliseconds max_wait,
                        int max_waiters);

  // Graceful stop: no new jobs start; running ones get `grace_s` to finish.
  // Returns true when every running job finished in time (the others are
  // put back in the queue, or left to their leases when the store is away).
  bool stop(double grace_s);

 private:
  struct Running {
    int attempt = 0;  // the fencing token of the claim
    std::string stage = "queued";
    double progress = 0.0;
    std::atomic<bool> cancel{false};
    std::atomic<bool> lost{false};  // the lease moved on: write nothing
    std::atomic<bool> finishing{false};  // its final write began (a heartbeat then may find no lease)
  };
  struct Execution {
    core::Result<core::JobOutput> outcome = core::Error{core::ErrorCode::kCancelled, "not run"};
    std::string stage;       // the last stage reached
    bool timed_out = false;
  };
  void workerLoop();
  void leaseLoop();        // heartbeats, expired leases, requeues that failed
  void listenLoop();       // shared store: wakes idle workers when another replica queues a job
  void renewLeases();
  void runOne(JobRecord job, Running& state);
  Execution execute(const JobRecord& job, Running& state);  // the job body with stage, cancel and time-limit hooks
  void recordFailure(JobRecord& job, const core::Error& error, const Execution& run) const;
  void storageFault(const JobRecord& job, const std::string& where, const std::string& detail);
  void giveBack(const std::string& id, int attempt);  // running -> queued, now or by the lease keeper
  void wakeWorkers(int jobs);

  MetadataStore& store_;
  BlobStore& blobs_;
  BlobCollection& blob_collection_;
  StorageHealth& storage_;
  Caches& caches_;
  Metrics& metrics_;
  const ServerConfig config_;
  JsonLog log_;
  std::string owner_;
  std::int64_t lease_ms_ = 30'000;
  std::chrono::milliseconds heartbeat_{1000};

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::condition_variable settled_;                          // a job finished or left here
  std::condition_variable lease_wake_;
  int waiters_ = 0;                                          // requests in waitUntilSettled
  int hints_ = 0;                                            // jobs known queued for idle workers
  int worker_count_ = 0;                                     // set by start()
  std::map<std::string, std::shared_ptr<Running>> running_;  // by job id
  std::vector<std::pair<std::string, int>> give_back_;       // (id, attempt) to requeue once the store answers
  std::map<std::string, int> storage_faults_;                // storage faults per job since its last finish
  bool stopping_ = false;
  bool abandoning_ = false;                                  // stop() past its grace period
  bool lease_stopping_ = false;
  std::vector<std::thread> workers_;
  std::thread lease_keeper_;
  std::thread listener_;
};

// The wire view of a stored job (with live stage/progress when running).
api::JobInfo jobInfoOf(const JobRecord& job, const std::optional<LiveProgress>& live);

}  // namespace server
