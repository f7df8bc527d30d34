#include "server/storage_health.h"

#include <chrono>

namespace server {

StorageHealth::StorageHealth(MetadataStore& store, BlobStore& blobs, const ServerConfig& config, JsonLog log)
    : store_(store), blobs_(blobs), config_(config), log_(std::move(log)) {}

StorageHealth::~StorageHealth() { stop(); }

void StorageHealth::start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] {
    std::unique_lock lock(mutex_);
    while (!stopping_) {
      const bool healthy = ok_;
      const double period_s = healthy ? config_.storage_probe_s : config_.storage_retry_s;
      // A fault reported meanwhile wakes it: the retries start at once.
      wake_.wait_for(lock, std::chrono::duration<double>(period_s), [&] { return stopping_ || ok_ != healthy; });
      if (stopping_) break;
      lock.unlock();
      probe();
      lock.lock();
    }
  });
}

void StorageHealth::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void StorageHealth::reportFault(const std::string& where, const std::string& detail) {
  faults_.fetch_add(1);
  const bool was_ok = ok_.exchange(false);
  log_.error("storage_fault", {{"where", where}, {"detail", detail}, {"ready", false}});
  if (was_ok) {
    std::lock_guard lock(mutex_);  // the prober is waiting or about to: it sees the change
    wake_.notify_all();
  }
}

bool StorageHealth::probe() {
  core::Status status = blobs_.probeWrite();
  if (status) status = store_.probeWrite();
  if (!status) {
    if (ok_.exchange(false)) {
      faults_.fetch_add(1);
      log_.error("storage_fault", {{"where", "probe"}, {"detail", status.error().message}, {"ready", false}});
    }
    return false;
  }
  if (!ok_.exchange(true)) log_.info("storage_recovered", {{"ready", true}});
  return true;
}

}  // namespace server
