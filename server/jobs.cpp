#include "server/jobs.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "api/error_codes.h"
#include "api/json.h"
#include "server/convert.h"

namespace server {

namespace {

using Clock = std::chrono::steady_clock;


}  // namespace

api::JobInfo jobInfoOf(const JobRecord& job, const std::optional<LiveProgress>& live) {
  api::JobInfo info;
  info.id = job.id;
  info.kind = api::jobKindName(job.kind);
  info.rig = job.rig;
  info.status = job.status;
  info.stage = job.stage;
  info.progress = job.status == api::JobStatus::kSucceeded ? 1.0 : 0.0;
  if (job.status == api::JobStatus::kRunning) {
    // Here: the worker's own view; elsewhere: its owner's last heartbeat.
    info.stage = live ? live->stage : job.stage;
    info.progress = live ? live->progress : job.progress;
  }
  info.attempts = job.attempts;
  info.cache_hit = job.cache_hit;
  info.has_components = job.status == api::JobStatus::kSucceeded && !job.components_blob.empty();
  info.files = job.input_names;
  info.created_at = formatTimestamp(job.created_ms);
  info.started_at = formatTimestamp(job.started_ms);
  info.finished_at = formatTimestamp(job.finished_ms);
  if (!job.timings_json.empty()) {
    const auto timings = nlohmann::json::parse(job.timings_json, nullptr, false);
    if (timings.is_object()) {
      for (const auto& [stage, ms] : timings.items()) {
        if (ms.is_number()) info.timings_ms[stage] = ms.get<double>();
      }
    }
  }
  if (!job.error_json.empty()) {
    const auto error = nlohmann::json::parse(job.error_json, nullptr, false);
    auto problem = api::problemFromJson(error);
    if (problem) info.error = std::move(*problem);
  }
  return info;
}

namespace {

// host:pid:random, unique among the replicas on one store.
std::string defaultReplicaId() {
  char host[256] = {0};
  if (gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return std::string(host) + ":" + std::to_string(getpid()) + ":" + secureRandomHex(4).value_or("0");
}

bool isStorageError(const core::Error& e) { return e.code == core::ErrorCode::kIo; }

}  // namespace

JobManager::JobManager(MetadataStore& store, BlobStore& blobs, BlobCollection& blob_collection, StorageHealth& storage,
                       Caches& caches, Metrics& metrics, const ServerConfig& config, JsonLog log)
    : store_(store), blobs_(blobs), blob_collection_(blob_collection), storage_(storage), caches_(caches), metrics_(metrics), config_(config), log_(std::move(log)) {
  owner_ = config_.replica_id.empty() ? defaultReplicaId() : config_.replica_id;
  lease_ms_ = std::max<std::int64_t>(1, std::llround(config_.lease_s * 1000.0));
  // A third of the lease, so two heartbeats may fail before it ends; at most a
  // second apart, so cancels and progress reach other replicas soon.
  heartbeat_ = std::chrono::milliseconds(std::clamp<std::int64_t>(lease_ms_ / 3, 10, 1000));
}

JobManager::~JobManager() { stop(0.0); }

void JobManager::start() {
  if (!store_.shared()) {
    // The embedded store has this one process: what it left running was
    // interrupted by a crash or a stop past its grace; run it again.
    int requeued = 0;
    for (const JobRecord& job : store_.unfinishedJobs()) {
      if (job.status != api::JobStatus::kRunning) continue;
      if (auto ok = store_.requeue(job.id, job.attempts); !ok) {
        log_.error("job_requeue_failed", {{"job", job.id}, {"tenant", job.tenant}, {"detail", ok.error().message}});
        continue;
      }
      ++requeued;
    }
    log_.info("jobs_recovered", {{"requeued_running", requeued}});
  }
  const int n = config_.workers > 0 ? config_.workers : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  {
    std::lock_guard lock(mutex_);
    worker_count_ = n;
    hints_ = n;  // look at once: the queue may hold jobs from before
  }
  log_.info("job_queue_started", {{"replica", owner_}, {"workers", n}, {"lease_s", config_.lease_s},
                                  {"store", store_.backend()}});
  for (int i = 0; i < n; ++i) workers_.emplace_back([this] { workerLoop(); });
  lease_keeper_ = std::thread([this] { leaseLoop(); });
  if (store_.shared()) listener_ = std::thread([this] { listenLoop(); });
}

api::Result<std::pair<JobRecord, bool>> JobManager::submit(const JobRecord& job) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return api::makeProblem(api::WireError::kNotReady, "the service is shutting down", "/v1/jobs");
  }
  // The capacity is checked by the store, in the transaction that inserts
  // (every replica's submissions counted).
  auto admitted = store_.admitJob(job, config_.queue_capacity);
  if (!admitted) {
    storage_.reportFault("job_submit", admitted.error().message);
    return api::makeProblem(api::WireError::kStorageUnavailable, "the job could not be stored: the service's storage "
                            "does not take writes now; nothing was accepted, submit it again", "/v1/jobs");
  }
  if (admitted->queue_full) {
    return api::makeProblem(api::WireError::kQueueFull,
                            "the job queue is full (" + std::to_string(config_.queue_capacity) +
                                " jobs waiting); retry after " + std::to_string(config_.retry_after_s) + " s",
                            "/v1/jobs");
  }
  if (admitted->inserted) wakeWorkers(1);
  return std::pair{std::move(admitted->job), admitted->inserted};
}

api::Result<JobRecord> JobManager::cancel(const std::string& tenant, const std::string& id) {
  const std::string instance = "/v1/jobs/" + id;
  const auto unavailable = [&](const core::Error& error) {
    storage_.reportFault("job_cancel", error.message);
    return api::makeProblem(api::WireError::kStorageUnavailable,
                            "the cancel could not be stored: the service's storage does not take writes now; cancel "
                            "the job again",
                            instance);
  };
  // A job may move on between the read and the guarded write (claimed,
  // finished): read again and decide again.
  for (int round = 0; round < 4; ++round) {
    auto job = store_.getJob(tenant, id);
    if (!job) return api::makeProblem(api::WireError::kNotFound, "no job " + id, instance);
    if (api::isFinal(job->status)) {
      return api::makeProblem(api::WireError::kConflict,
                              "job " + id + " is already " + api::jobStatusName(job->status) + "; nothing to cancel",
                              instance);
    }
    if (job->status == api::JobStatus::kRunning) {
      core::Status asked = core::Ok{};
      {
        // Held across the store write: a worker of this replica registering
        // the job meanwhile either is seen here or, after this, reads the
        // flag from the store (workerLoop). Others see it at their next heartbeat.
        std::lock_guard lock(mutex_);
        if (auto it = running_.find(id); it != running_.end()) it->second->cancel = true;
        asked = store_.requestCancel(id);
      }
      if (!asked && isStorageError(asked.error())) return unavailable(asked.error());
      if (!asked) continue;
      log_.info("job_cancel_requested", {{"job", id}, {"tenant", tenant}});
      job->cancel_requested = true;
      return *job;
    }
    JobRecord cancelled = *job;
    cancelled.status = api::JobStatus::kCancelled;
    cancelled.stage = "cancelled";
    cancelled.finished_ms = nowMs();
    cancelled.error_json =
        api::dumpJson(api::toJson(api::makeProblem(api::WireError::kJobCancelled, "cancelled while queued", instance)));
    auto ok = store_.markFinished(cancelled, job->attempts);  // refused once a worker claimed it
    if (!ok && isStorageError(ok.error())) return unavailable(ok.error());
    if (!ok) continue;
    {
      std::lock_guard lock(mutex_);
      storage_faults_.erase(id);
      settled_.notify_all();
    }
    metrics_.countJobOutcome("cancelled");
    log_.info("job_cancelled", {{"job", id}, {"tenant", tenant}, {"while", "queued"}});
    return cancelled;
  }
  return api::makeProblem(api::WireError::kConflict, "job " + id + " kept changing state; cancel it again", instance);
}

std::optional<LiveProgress> JobManager::live(const std::string& id) const {
  std::lock_guard lock(mutex_);
  const auto it = running_.find(id);
  if (it == running_.end()) return std::nullopt;
  return LiveProgress{it->second->stage, it->second->progress, it->second->cancel.load()};
}

int JobManager::queueDepth() {
  auto queued = store_.queuedJobs();
  return queued ? static_cast<int>(*queued) : 0;
}

int JobManager::runningJobs() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(running_.size());
}

bool JobManager::stop(double grace_s) {
  std::unique_lock lock(mutex_);
  stopping_ = true;
  wake_.notify_all();
  settled_.notify_all();
  const bool finished = idle_.wait_for(lock, std::chrono::duration<double>(grace_s), [&] { return running_.empty(); });
  if (!finished) {
    // Past the grace period: stop them at their next stage boundary and put
    // them back in the queue (not cancelled: nobody asked).
    abandoning_ = true;
    for (auto& [id, r] : running_) r->cancel = true;
  }
  lock.unlock();
  for (auto& w : workers_) {
    if (w.joinable()) w.join();
  }
  workers_.clear();
  lock.lock();
  lease_stopping_ = true;  // every lease is given back or left to expire now
  lease_wake_.notify_all();
  lock.unlock();
  if (lease_keeper_.joinable()) lease_keeper_.join();
  if (listener_.joinable()) listener_.join();
  return finished;
}

void JobManager::wakeWorkers(int jobs) {
  std::lock_guard lock(mutex_);
  hints_ = std::min(hints_ + jobs, worker_count_ + 1);
  if (jobs == 1) {
    wake_.notify_one();
  } else {
    wake_.notify_all();
  }
}

void JobManager::workerLoop() {
  const auto poll = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(config_.poll_s));
  auto next_look = Clock::now();
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      // Look when a job was submitted or requeued here, or every poll (other
      // replicas' jobs); never while storage does not take writes (its health
      // changes without a notification here, hence the bounded wait).
      for (;;) {
        if (stopping_) return;  // queued jobs stay queued in the store
        if (storage_.ok() && (hints_ > 0 || Clock::now() >= next_look)) break;
        wake_.wait_for(lock, std::min<Clock::duration>(poll, std::chrono::milliseconds(200)));
      }
      if (hints_ > 0) --hints_;
    }
    auto claimed = store_.claimNextJob(owner_, lease_ms_);
    if (!claimed) {
      // Whether the claim landed is unknown: if it did, its lease runs out
      // unrenewed and the job is requeued.
      storage_.reportFault("job_claim", claimed.error().message);
      next_look = Clock::now() + poll;
      continue;
    }
    if (!*claimed) {
      next_look = Clock::now() + poll;
      continue;
    }
    next_look = Clock::now();  // there may be more
    JobRecord job = std::move(**claimed);
    auto state = std::make_shared<Running>();
    state->attempt = job.attempts;
    bool stop_now = false;
    {
      std::lock_guard lock(mutex_);
      stop_now = stopping_;
      if (!stop_now) running_.emplace(job.id, state);
    }
    if (stop_now) {  // claimed as the server stopped: back in the queue
      giveBack(job.id, job.attempts);
      return;
    }
    // A cancel asked between the claim and the registration above is in the
    // store only (cancel holds mutex_ across its write).
    if (auto now = store_.getJob(job.tenant, job.id); now && now->cancel_requested) state->cancel = true;
    const std::string id = job.id;
    runOne(std::move(job), *state);
    std::lock_guard lock(mutex_);
    running_.erase(id);
    settled_.notify_all();
    if (running_.empty()) idle_.notify_all();
  }
}

bool JobManager::waitUntilSettled(const std::string& tenant, const std::string& id, std::chrono::milliseconds max_wait,
                                  int max_waiters) {
  const auto deadline = Clock::now() + max_wait;
  const auto unsettled = [&] {
    auto job = store_.getJob(tenant, id);
    return job && !api::isFinal(job->status);
  };
  {
    std::lock_guard lock(mutex_);
    if (stopping_ || waiters_ >= max_waiters) return false;
    ++waiters_;
  }
  bool waited = false;
  while (unsettled()) {
    std::unique_lock lock(mutex_);
    if (stopping_ || Clock::now() >= deadline) break;
    waited = true;
    // A job finishing here notifies; one on another replica is seen by the
    // next look at the store.
    settled_.wait_for(lock, std::min<Clock::duration>(deadline - Clock::now(), std::chrono::milliseconds(250)));
  }
  std::lock_guard lock(mutex_);
  --waiters_;
  return waited;
}

void JobManager::leaseLoop() {
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      lease_wake_.wait_for(lock, heartbeat_, [&] { return lease_stopping_; });
      if (lease_stopping_) return;
    }
    renewLeases();
    std::vector<std::pair<std::string, int>> give_back;
    {
      std::lock_guard lock(mutex_);
      give_back.swap(give_back_);
    }
    for (const auto& [id, attempt] : give_back) giveBack(id, attempt);
    auto expired = store_.requeueExpiredLeases();
    if (!expired) {
      log_.warn("lease_scan_failed", {{"detail", expired.error().message}});
      continue;
    }
    for (const std::string& id : *expired) {
      metrics_.countLeaseEvent(Metrics::LeaseEvent::kExpired);
      log_.warn("job_lease_expired", {{"job", id}, {"replica", owner_}});
    }
    if (!expired->empty()) wakeWorkers(static_cast<int>(expired->size()));
  }
}

void JobManager::listenLoop() {
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (lease_stopping_) return;
    }
    // Bounded, so a stop is seen within half a second.
    auto announced = store_.waitForQueuedJobs(std::chrono::milliseconds(500));
    if (announced && *announced) {
      int workers = 0;
      {
        std::lock_guard lock(mutex_);
        workers = worker_count_;
      }
      wakeWorkers(workers);
    }
    if (!announced) {  // the store is away: polling carries on; listen again in a while
      std::unique_lock lock(mutex_);
      lease_wake_.wait_for(lock, heartbeat_, [&] { return lease_stopping_; });
    }
  }
}

void JobManager::renewLeases() {
  std::vector<LeaseRenewal> renewals;
  std::vector<std::shared_ptr<Running>> states;
  {
    std::lock_guard lock(mutex_);
    for (const auto& [id, state] : running_) {
      if (state->lost) continue;
      renewals.push_back({id, state->attempt, state->stage, state->progress});
      states.push_back(state);
    }
  }
  if (renewals.empty()) return;
  auto answers = store_.renewLeases(owner_, renewals, lease_ms_);
  if (!answers) {
    // The lease runs out unless a later heartbeat gets through: the job then
    // runs elsewhere, and this worker's writes are refused by the fence.
    log_.warn("lease_renewal_failed", {{"jobs", renewals.size()}, {"detail", answers.error().message}});
    return;
  }
  for (std::size_t i = 0; i < answers->size() && i < states.size(); ++i) {
    if ((*answers)[i] == LeaseState::kCancelRequested) states[i]->cancel = true;
    // A job whose worker began its final write may be finished already: its
    // own fenced write tells whether the lease had moved on.
    if ((*answers)[i] == LeaseState::kLost && !states[i]->finishing) {
      states[i]->lost = true;
      states[i]->cancel = true;  // stop at the next stage boundary, write nothing
      metrics_.countLeaseEvent(Metrics::LeaseEvent::kFencingRejected);
      log_.warn("job_lease_lost", {{"job", renewals[i].id}, {"attempt", renewals[i].attempt}, {"replica", owner_}});
    }
  }
}

void JobManager::giveBack(const std::string& id, int attempt) {
  auto ok = store_.requeue(id, attempt);
  if (ok || !isStorageError(ok.error())) return;  // requeued, or moved on already (finished, claimed again)
  std::lock_guard lock(mutex_);
  if (!lease_stopping_) give_back_.emplace_back(id, attempt);  // else its lease runs out
}

void JobManager::storageFault(const JobRecord& job, const std::string& where, const std::string& detail) {
  storage_.reportFault(where, "job " + job.id + ": " + detail);
  int count = 0;
  {
    std::lock_guard lock(mutex_);
    count = ++storage_faults_[job.id];
  }
  if (count <= config_.storage_retries_per_job) {
    giveBack(job.id, job.attempts);  // runs again once storage takes writes
    return;
  }
  // The job's own data keeps failing though the probe passes between tries (a
  // corrupted or vanished blob): it fails, saying so without server paths.
  JobRecord failed;
  failed.id = job.id;
  failed.status = api::JobStatus::kFailed;
  failed.error_json = api::dumpJson(api::toJson(api::makeProblem(
      api::WireError::kInternal,
      "the service could not read or write this job's stored data " + std::to_string(count) +
          " times (the cause is in the service log); submit the job again",
      "/v1/jobs/" + job.id)));
  if (!store_.markFinished(failed, job.attempts)) {
    giveBack(job.id, job.attempts);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    storage_faults_.erase(job.id);
  }
  metrics_.countJobOutcome("failed");
  log_.error("job_failed_on_storage", {{"job", job.id}, {"tenant", job.tenant}, {"tries", count}});
}

void JobManager::runOne(JobRecord job, Running& state) {
  const std::string& id = job.id;
  const std::string& tenant = job.tenant;
  const int attempt = job.attempts;
  if (attempt > 1) metrics_.countLeaseEvent(Metrics::LeaseEvent::kRescued);
  metrics_.observeStage("queue", static_cast<double>(std::max<std::int64_t>(0, job.started_ms - job.created_ms)) / 1000.0);
  log_.info("job_started", {{"job", id}, {"tenant", tenant}, {"kind", api::jobKindName(job.kind)}, {"attempt", attempt},
                            {"replica", owner_}});

  const auto t_start = Clock::now();
  Execution run = execute(job, state);
  state.finishing = true;
  if (state.lost) {
    log_.warn("job_abandoned", {{"job", id}, {"tenant", tenant}, {"attempt", attempt}, {"reason", "lease lost"}});
    return;
  }
  if (!run.outcome && isStorageError(run.outcome.error())) {
    storageFault(job, "job_inputs", run.outcome.error().message);
    return;
  }
  job.finished_ms = nowMs();
  // Held until the row references the result blobs: a job deleted meanwhile
  // may share their bytes (same inputs, same result) and must not remove them.
  std::shared_lock collection(blob_collection_);
  if (run.outcome) {
    const core::JobOutput* out = &*run.outcome;
    // Results are durable before the row points at them: a crash in between
    // leaves the job running (requeued), never half-written. A refused output
    // (a fit its gate failed) has diagnostics and no result.
    auto result_blob = out->refused ? core::Result<std::string>(std::string()) : blobs_.put(out->glb);
    auto diagnostics_blob = blobs_.put(std::span(reinterpret_cast<const std::uint8_t*>(out->diagnostics.data()),
                                                 out->diagnostics.size()));
    auto components_blob = out->refused || out->components.empty()
                               ? core::Result<std::string>(std::string())
                               : blobs_.put(std::span(reinterpret_cast<const std::uint8_t*>(out->components.data()),
                                                      out->components.size()));
    if (!result_blob || !diagnostics_blob || !components_blob) {
      const core::Error& e = !result_blob        ? result_blob.error()
                             : !diagnostics_blob ? diagnostics_blob.error()
                                                 : components_blob.error();
      storageFault(job, "job_result", e.message);
      return;
    }
    job.status = api::JobStatus::kSucceeded;
    job.stage = "done";
    job.result_blob = *result_blob;
    job.diagnostics_blob = *diagnostics_blob;
    job.components_blob = *components_blob;
    job.cache_hit = out->cache_hit;
    job.timings_json = nlohmann::json(out->timings_ms).dump();
    if (out->refused) recordFailure(job, *out->refused, run);
  }
  if (!run.outcome) {
    const core::Error* error = &run.outcome.error();
    bool abandoned = false;
    {
      std::lock_guard lock(mutex_);
      abandoned = abandoning_ && error->code == core::ErrorCode::kCancelled;
    }
    if (abandoned) {
      giveBack(id, attempt);
      log_.warn("job_requeued_at_shutdown", {{"job", id}, {"tenant", tenant}});
      return;
    }
    recordFailure(job, *error, run);
  }
  if (auto ok = store_.markFinished(job, attempt); !ok) {
    if (isStorageError(ok.error())) {
      storageFault(job, "job_finish", ok.error().message);
    } else {
      // The fence: this attempt's lease had moved on (another replica runs
      // or ran the job); its result is not written over the new owner's.
      metrics_.countLeaseEvent(Metrics::LeaseEvent::kFencingRejected);
      log_.warn("job_result_fenced", {{"job", id}, {"tenant", tenant}, {"attempt", attempt}, {"detail", ok.error().message}});
    }
    return;
  }
  {
    std::lock_guard lock(mutex_);
    storage_faults_.erase(id);
  }
  metrics_.countJobOutcome(api::jobStatusName(job.status));
  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t_start).count();
  if (job.status == api::JobStatus::kSucceeded) {
    log_.info("job_succeeded", {{"job", id}, {"tenant", tenant}, {"ms", total_ms}, {"cache_hit", job.cache_hit}});
  } else {
    log_.warn("job_" + std::string(api::jobStatusName(job.status)),
              {{"job", id}, {"tenant", tenant}, {"ms", total_ms}, {"error", nlohmann::json::parse(job.error_json)}});
  }
}

JobManager::Execution JobManager::execute(const JobRecord& job, Running& state) {
  Execution run;
  const auto t_start = Clock::now();
  const auto deadline = t_start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(config_.job_time_limit_s));
  auto stage_start = t_start;
  core::StageHook on_stage = [&](std::string_view stage, double progress) {
    const auto now = Clock::now();
    if (!run.stage.empty()) metrics_.observeStage(run.stage, std::chrono::duration<double>(now - stage_start).count());
    run.stage = stage;
    stage_start = now;
    {
      std::lock_guard lock(mutex_);
      state.stage = stage;
      state.progress = progress;
    }
    if (now > deadline) run.timed_out = true;
    return !(state.cancel.load() || run.timed_out);
  };
  std::optional<RigRecord> rig;
  if (!job.rig.empty()) rig = store_.getRig(job.tenant, job.rig);
  if (!job.rig.empty() && !rig) {
    run.outcome = core::makeError(core::ErrorCode::kInvalidArgument, "rig " + job.rig + " was deleted before the job ran");
  } else {
    run.outcome = runJob(job, rig ? &*rig : nullptr, blobs_, caches_, on_stage, config_.threads_per_job);
  }
  if (!run.stage.empty()) metrics_.observeStage(run.stage, std::chrono::duration<double>(Clock::now() - stage_start).count());
  return run;
}

void JobManager::recordFailure(JobRecord& job, const core::Error& error, const Execution& run) const {
  const std::string instance = "/v1/jobs/" + job.id;
  api::Problem problem = problemFromCoreError(error, instance);
  if (error.code == core::ErrorCode::kCancelled && run.timed_out) {
    problem = api::makeProblem(api::WireError::kJobTimeout,
                               "job " + job.id + " exceeded the time limit of " + std::to_string(config_.job_time_limit_s) +
                                   " s (stopped before stage '" + run.stage + "')",
                               instance);
  }
  job.status = error.code == core::ErrorCode::kCancelled && !run.timed_out ? api::JobStatus::kCancelled
                                                                            : api::JobStatus::kFailed;
  job.stage = run.stage.empty() ? "failed" : run.stage;
  job.error_json = api::dumpJson(api::toJson(problem));
}

}  // namespace server
