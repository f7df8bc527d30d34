#include "server/retention.h"

#include <chrono>
#include <set>

#include "server/timestamps.h"

namespace server {

JobDeletion deleteJob(MetadataStore& store, BlobStore& blobs, BlobCollection& blob_collection, Metrics& metrics,
                      const JsonLog& log, const std::string& tenant, const std::string& id, const char* reason) {
  auto job = store.getJob(tenant, id);
  if (!job) return JobDeletion::kAbsent;
  if (!api::isFinal(job->status)) return JobDeletion::kUnfinished;
  std::unique_lock collection(blob_collection);
  if (!blob_collection.mayCollect()) {
    log.error("job_delete_failed", {{"job", id}, {"tenant", tenant}, {"detail", "the blob-collection lock could not be taken"}});
    return JobDeletion::kStoreError;  // retried: by the next sweep, or by the client after the 503
  }
  auto deleted = store.deleteFinishedJob(tenant, id);
  if (!deleted) {
    log.error("job_delete_failed", {{"job", id}, {"tenant", tenant}, {"detail", deleted.error().message}});
    return JobDeletion::kStoreError;
  }
  if (!*deleted) return JobDeletion::kAbsent;  // deleted by a concurrent request (a final job never changes)
  std::set<std::string> hashes{job->result_blob, job->diagnostics_blob, job->components_blob};
  for (const auto& [field, hash] : job->inputs) hashes.insert(hash);
  const int removed = blob_collection.removeUnreferenced(blobs, hashes);
  metrics.countJobDeleted(reason);
  log.info("job_deleted", {{"job", id}, {"tenant", tenant}, {"reason", reason}, {"blobs_removed", removed}});
  return JobDeletion::kDeleted;
}

RetentionSweeper::RetentionSweeper(MetadataStore& store, BlobStore& blobs, BlobCollection& blob_collection,
                                   Metrics& metrics, const ServerConfig& config, JsonLog log)
    : store_(store), blobs_(blobs), blob_collection_(blob_collection), metrics_(metrics), config_(config), log_(std::move(log)) {}

RetentionSweeper::~RetentionSweeper() { stop(); }

void RetentionSweeper::start() {
  if (config_.keep_jobs_days <= 0.0 || thread_.joinable()) return;
  thread_ = std::thread([this] {
    const auto period = std::chrono::duration<double>(config_.retention_sweep_s);
    std::unique_lock lock(mutex_);
    while (!stopping_) {
      lock.unlock();
      sweep(nowMs());
      lock.lock();
      wake_.wait_for(lock, period, [this] { return stopping_; });
    }
  });
}

void RetentionSweeper::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

int RetentionSweeper::sweep(std::int64_t now_ms) {
  if (config_.keep_jobs_days <= 0.0) return 0;
  const auto keep_ms = static_cast<std::int64_t>(config_.keep_jobs_days * 86'400'000.0);
  const std::int64_t cutoff = now_ms - keep_ms;
  // In pages, so one sweep never holds the store (or the collection lock) for long.
  constexpr int kPage = 256;
  int deleted = 0;
  for (;;) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) break;
    }
    const auto expired = store_.finishedJobsBefore(cutoff, kPage);
    int page_deleted = 0;
    for (const auto& [tenant, id] : expired) {
      if (deleteJob(store_, blobs_, blob_collection_, metrics_, log_, tenant, id, "retention") == JobDeletion::kDeleted) {
        ++page_deleted;
      }
    }
    deleted += page_deleted;
    if (static_cast<int>(expired.size()) < kPage || page_deleted == 0) break;
  }
  if (deleted > 0) log_.info("retention_sweep", {{"jobs_deleted", deleted}, {"keep_jobs_days", config_.keep_jobs_days}});
  return deleted;
}

}  // namespace server
