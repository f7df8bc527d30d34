// Deleting finished jobs with the blobs only they referenced: DELETE
// /v1/jobs/{id} and the retention sweep (jobs finished more than
// ServerConfig::keep_jobs_days ago). Blobs are content-addressed and shared
// (two jobs on the same target share its blob), so a blob goes only when no
// rig or job row references it any more, checked under the exclusive
// blob-collection lock that uploads and workers hold shared while they write
// blobs a row is about to reference.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <shared_mutex>

#include "server/blob_collection.h"
#include <string>
#include <thread>

#include "server/config.h"
#include "server/json_log.h"
#include "server/metrics.h"
#include "server/store.h"

namespace server {

enum class JobDeletion { kDeleted, kAbsent, kUnfinished, kStoreError };

// Deletes the tenant's job when it is final; queued or running jobs are left
// alone (kUnfinished: cancel first). `reason` ("request", "retention") goes to
// the log and the metrics.
JobDeletion deleteJob(MetadataStore& store, BlobStore& blobs, BlobCollection& blob_collection, Metrics& metrics,
                      const JsonLog& log, const std::string& tenant, const std::string& id, const char* reason);

// A thread deleting expired jobs every config.retention_sweep_s (none when
// keep_jobs_days is 0).
class RetentionSweeper {
 public:
  RetentionSweeper(MetadataStore& store, BlobStore& blobs, BlobCollection& blob_collection, Metrics& metrics,
                   const ServerConfig& config, JsonLog log);
  ~RetentionSweeper();  // stop()
  RetentionSweeper(const RetentionSweeper&) = delete;
  RetentionSweeper& operator=(const RetentionSweeper&) = delete;

  void start();  // sweeps at once, then every period
  void stop();
  // Deletes every final job that finished before now_ms - keep_jobs_days;
  // returns how many went.
  int sweep(std::int64_t now_ms);

 private:
  MetadataStore& store_;
  BlobStore& blobs_;
  BlobCollection& blob_collection_;
  Metrics& metrics_;
  const ServerConfig& config_;
  JsonLog log_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace server
