// Whether the data directory takes writes. A failed store or blob write (a
// full or read-only disk, a device error) reported here turns readiness red:
// /readyz and every request that would write answer 503 storage-unavailable
// with Retry-After, and workers take no job, so accepted jobs stay queued
// instead of failing. A probe (a 64 KiB file written, fsynced and removed
// beside the blobs, and one write transaction in the metadata store) runs
// every config.storage_probe_s while healthy and every
// config.storage_retry_s while not; the first that passes turns it green and
// the waiting jobs run. What failed, with its paths, goes to the log only:
// tenants never see server paths.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

#include "server/config.h"
#include "server/json_log.h"
#include "server/store.h"

namespace server {

class StorageHealth {
 public:
  StorageHealth(MetadataStore& store, BlobStore& blobs, const ServerConfig& config, JsonLog log);
  ~StorageHealth();  // stop()
  StorageHealth(const StorageHealth&) = delete;
  StorageHealth& operator=(const StorageHealth&) = delete;

  void start();
  void stop();
  bool ok() const { return ok_.load(); }
  // A write (or read) of the store or a blob failed in `where` (an event
  // name: "job_result", "upload"); `detail` is logged, never sent.
  void reportFault(const std::string& where, const std::string& detail);
  // Runs the probe now; true when storage takes writes.
  bool probe();
  std::int64_t faults() const { return faults_.load(); }

 private:
  MetadataStore& store_;
  BlobStore& blobs_;
  const ServerConfig& config_;
  JsonLog log_;
  std::atomic<bool> ok_{true};
  std::atomic<std::int64_t> faults_{0};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace server
