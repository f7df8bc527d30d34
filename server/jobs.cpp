#include "server/jobs.h"

#include <algorithm>
#include <chrono>

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
  if (job.status == api::JobStatus::kRunning && live) {
    info.stage = live->stage;
    info.progress = live->progress;
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

JobManager::JobManager(MetadataStore& store, BlobStore& blobs, std::shared_mutex& blob_collection, StorageHealth& storage,
                       Caches& caches, Metrics& metrics, const ServerConfig& config, JsonLog log)
    : store_(store), blobs_(blobs), blob_collection_(blob_collection), storage_(storage), caches_(caches), metrics_(metrics), config_(config), log_(std::move(log)) {}

JobManager::~JobManager() { stop(0.0); }

void JobManager::start() {
  std::vector<JobRecord> unfinished = store_.unfinishedJobs();
  int requeued = 0;
  {
    std::lock_guard lock(mutex_);
    for (const JobRecord& job : unfinished) {
      if (job.status == api::JobStatus::kRunning) {
        // Interrupted by a crash or a stop past its grace: run it again from its inputs.
        if (auto ok = store_.requeue(job.id); !ok) {
          log_.error("job_requeue_failed", {{"job", job.id}, {"tenant", job.tenant}, {"detail", ok.error().message}});
          continue;
        }
        ++requeued;
      }
      queue_.emplace_back(job.tenant, job.id);
    }
  }
  log_.info("jobs_recovered", {{"queued", unfinished.size()}, {"requeued_running", requeued}});
  const int n = config_.workers > 0 ? config_.workers : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  for (int i = 0; i < n; ++i) workers_.emplace_back([this] { workerLoop(); });
}

api::Result<std::pair<JobRecord, bool>> JobManager::submit(const JobRecord& job) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return api::makeProblem(api::WireError::kNotReady, "the service is shutting down", "/v1/jobs");
    if (static_cast<int>(queue_.size()) + reserved_ >= config_.queue_capacity) {
      return api::makeProblem(api::WireError::kQueueFull,
                              "the job queue is full (" + std::to_string(config_.queue_capacity) +
                                  " jobs waiting); retry after " + std::to_string(config_.retry_after_s) + " s",
                              "/v1/jobs");
    }
    ++reserved_;  // holds a slot while the row is committed outside the lock
  }
  auto inserted = store_.insertJob(job);
  std::lock_guard lock(mutex_);
  --reserved_;
  if (!inserted) {
    storage_.reportFault("job_submit", inserted.error().message);
    return api::makeProblem(api::WireError::kStorageUnavailable, "the job could not be stored: the service's storage "
                            "does not take writes now; nothing was accepted, submit it again", "/v1/jobs");
  }
  if (inserted->second) {
    queue_.emplace_back(inserted->first.tenant, inserted->first.id);
    wake_.notify_one();
  }
  return std::move(*inserted);
}

api::Result<JobRecord> JobManager::cancel(const std::string& tenant, const std::string& id) {
  const std::string instance = "/v1/jobs/" + id;
  std::unique_lock lock(mutex_);  // excludes a worker starting this job meanwhile
  auto job = store_.getJob(tenant, id);
  if (!job) return api::makeProblem(api::WireError::kNotFound, "no job " + id, instance);
  if (api::isFinal(job->status)) {
    return api::makeProblem(api::WireError::kConflict,
                            "job " + id + " is already " + api::jobStatusName(job->status) + "; nothing to cancel", instance);
  }
  if (auto it = running_.find(id); it != running_.end()) {
    it->second->cancel = true;  // the worker stops at the next stage boundary
    log_.info("job_cancel_requested", {{"job", id}, {"tenant", tenant}});
    return *job;
  }
  std::erase_if(queue_, [&](const auto& entry) { return entry.second == id; });
  settled_.notify_all();  // waiters re-read the store after this function's commit (they need mutex_)
  job->status = api::JobStatus::kCancelled;
  job->stage = "cancelled";
  job->finished_ms = nowMs();
  job->error_json = api::dumpJson(api::toJson(api::makeProblem(api::WireError::kJobCancelled, "cancelled while queued", instance)));
  if (auto ok = store_.markFinished(*job); !ok) {
    storage_.reportFault("job_cancel", ok.error().message);
    queue_.emplace_front(tenant, id);  // still queued, as the store says
    return api::makeProblem(api::WireError::kStorageUnavailable,
                            "the cancel could not be stored: the service's storage does not take writes now; the job is "
                            "still queued, cancel it again",
                            instance);
  }
  requeue_first_.erase(id);
  storage_faults_.erase(id);
  metrics_.countJobOutcome("cancelled");
  log_.info("job_cancelled", {{"job", id}, {"tenant", tenant}, {"while", "queued"}});
  return *job;
}

std::optional<LiveProgress> JobManager::live(const std::string& id) const {
  std::lock_guard lock(mutex_);
  const auto it = running_.find(id);
  if (it == running_.end()) return std::nullopt;
  return LiveProgress{it->second->stage, it->second->progress, it->second->cancel.load()};
}

int JobManager::queueDepth() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(queue_.size());
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
    // them back in the queue of the store (not cancelled: nobody asked).
    abandoning_ = true;
    for (auto& [id, r] : running_) r->cancel = true;
  }
  lock.unlock();
  for (auto& w : workers_) {
    if (w.joinable()) w.join();
  }
  workers_.clear();
  return finished;
}

void JobManager::workerLoop() {
  for (;;) {
    std::pair<std::string, std::string> next;
    bool requeue_first = false;
    {
      std::unique_lock lock(mutex_);
      // No job starts while storage does not take writes; its health changes
      // without a notification here, hence the bounded wait.
      while (!stopping_ && (queue_.empty() || !storage_.ok())) wake_.wait_for(lock, std::chrono::milliseconds(200));
      if (stopping_) return;  // queued jobs stay queued in the store
      next = std::move(queue_.front());
      queue_.pop_front();
      requeue_first = requeue_first_.erase(next.second) > 0;
      running_.emplace(next.second, std::make_shared<Running>());
    }
    const Retry retry = runOne(next.first, next.second, requeue_first);
    std::lock_guard lock(mutex_);
    running_.erase(next.second);
    if (retry != Retry::kNo) {
      // Back at the front, to run once storage takes writes again (a stop
      // meanwhile leaves it in the store, recovered at the next start).
      queue_.push_front(next);
      if (retry == Retry::kRunning) requeue_first_.insert(next.second);
    }
    settled_.notify_all();
    if (running_.empty()) idle_.notify_all();
  }
}

bool JobManager::waitUntilSettled(const std::string& id, std::chrono::milliseconds max_wait, int max_waiters) {
  std::unique_lock lock(mutex_);
  auto unsettled = [&] {
    return running_.count(id) > 0 ||
           std::any_of(queue_.begin(), queue_.end(), [&](const auto& entry) { return entry.second == id; });
  };
  if (stopping_ || !unsettled() || waiters_ >= max_waiters) return false;
  ++waiters_;
  settled_.wait_for(lock, max_wait, [&] { return stopping_ || !unsettled(); });
  --waiters_;
  return true;
}

JobManager::Retry JobManager::storageFault(const std::string& tenant, const std::string& id, const std::string& where,
                                          const std::string& detail, Retry retry) {
  storage_.reportFault(where, "job " + id + ": " + detail);
  int count = 0;
  {
    std::lock_guard lock(mutex_);
    count = ++storage_faults_[id];
  }
  if (count <= config_.storage_retries_per_job) return retry;
  // The job's own data keeps failing though the probe passes between tries (a
  // corrupted or vanished blob): it fails, saying so without server paths.
  JobRecord failed;
  failed.id = id;
  failed.status = api::JobStatus::kFailed;
  failed.error_json = api::dumpJson(api::toJson(api::makeProblem(
      api::WireError::kInternal,
      "the service could not read or write this job's stored data " + std::to_string(count) +
          " times (the cause is in the service log); submit the job again",
      "/v1/jobs/" + id)));
  if (!store_.markFinished(failed)) return retry;
  {
    std::lock_guard lock(mutex_);
    storage_faults_.erase(id);
  }
  metrics_.countJobOutcome("failed");
  log_.error("job_failed_on_storage", {{"job", id}, {"tenant", tenant}, {"tries", count}});
  return Retry::kNo;
}

JobManager::Retry JobManager::runOne(const std::string& tenant, const std::string& id, bool requeue_first) {
  std::shared_ptr<Running> state;
  {
    std::lock_guard lock(mutex_);
    state = running_.at(id);
  }
  const auto isStorage = [](const core::Error& e) { return e.code == core::ErrorCode::kIo; };
  if (requeue_first) {  // left running by a storage fault after it started
    if (auto ok = store_.requeue(id); !ok) {
      return isStorage(ok.error()) ? storageFault(tenant, id, "job_requeue", ok.error().message, Retry::kRunning) : Retry::kNo;
    }
  }
  auto job = store_.getJob(tenant, id);
  if (!job || api::isFinal(job->status)) return Retry::kNo;  // cancelled while queued, or deleted
  const std::int64_t started_ms = nowMs();
  if (auto ok = store_.markRunning(id, started_ms, false); !ok) {
    if (isStorage(ok.error())) return storageFault(tenant, id, "job_start", ok.error().message, Retry::kQueued);
    log_.error("job_start_failed", {{"job", id}, {"tenant", tenant}, {"detail", ok.error().message}});
    return Retry::kNo;
  }
  job->status = api::JobStatus::kRunning;
  job->attempts += 1;
  job->started_ms = started_ms;
  metrics_.observeStage("queue", static_cast<double>(started_ms - job->created_ms) / 1000.0);
  log_.info("job_started", {{"job", id}, {"tenant", tenant}, {"kind", api::jobKindName(job->kind)}, {"attempt", job->attempts}});

  const auto t_start = Clock::now();
  Execution run = execute(*job, *state);
  if (!run.outcome && isStorage(run.outcome.error())) {
    return storageFault(tenant, id, "job_inputs", run.outcome.error().message, Retry::kRunning);
  }
  job->finished_ms = nowMs();
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
      return storageFault(tenant, id, "job_result", e.message, Retry::kRunning);
    }
    job->status = api::JobStatus::kSucceeded;
    job->stage = "done";
    job->result_blob = *result_blob;
    job->diagnostics_blob = *diagnostics_blob;
    job->components_blob = *components_blob;
    job->cache_hit = out->cache_hit;
    job->timings_json = nlohmann::json(out->timings_ms).dump();
    if (out->refused) recordFailure(*job, *out->refused, run);
  }
  if (!run.outcome) {
    const core::Error* error = &run.outcome.error();
    bool abandoned = false;
    {
      std::lock_guard lock(mutex_);
      abandoned = abandoning_ && error->code == core::ErrorCode::kCancelled;
    }
    if (abandoned) {
      if (auto ok = store_.requeue(id); !ok) {
        log_.error("job_requeue_failed", {{"job", id}, {"tenant", tenant}, {"detail", ok.error().message}});
      }
      log_.warn("job_requeued_at_shutdown", {{"job", id}, {"tenant", tenant}});
      return Retry::kNo;
    }
    recordFailure(*job, *error, run);
  }
  if (auto ok = store_.markFinished(*job); !ok) {
    if (isStorage(ok.error())) return storageFault(tenant, id, "job_finish", ok.error().message, Retry::kRunning);
    log_.error("job_finish_failed", {{"job", id}, {"tenant", tenant}, {"detail", ok.error().message}});
    return Retry::kNo;
  }
  {
    std::lock_guard lock(mutex_);
    storage_faults_.erase(id);
  }
  metrics_.countJobOutcome(api::jobStatusName(job->status));
  const double total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t_start).count();
  if (job->status == api::JobStatus::kSucceeded) {
    log_.info("job_succeeded", {{"job", id}, {"tenant", tenant}, {"ms", total_ms}, {"cache_hit", job->cache_hit}});
  } else {
    log_.warn("job_" + std::string(api::jobStatusName(job->status)),
              {{"job", id}, {"tenant", tenant}, {"ms", total_ms}, {"error", nlohmann::json::parse(job->error_json)}});
  }
  return Retry::kNo;
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
