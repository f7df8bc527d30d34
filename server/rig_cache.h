// Prepared source rigs (parsed rig, TPS factorisations, surface index, dense
// centres) keyed by rig content id, bounded by bytes, least recently used
// first out. Concurrent jobs on one rig prepare it once: the first caller runs
// the preparation, the others wait for its result (no thundering herd).
// Entries are immutable and shared; eviction only drops the cache's reference.
#pragma once

#include <cstdint>
#include <functional>
#include <future>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "core/error.h"
#include "core/transfer.h"

namespace server {

using PreparedRigPtr = std::shared_ptr<const core::PreparedRig>;

struct CacheLookup {
  PreparedRigPtr rig;
  bool hit = false;        // true: no source-only work was done for this caller
};

struct CacheStats {
  std::int64_t bytes = 0, capacity_bytes = 0, entries = 0;
  std::int64_t hits = 0, misses = 0, evictions = 0;
};

class RigCache {
 public:
  explicit RigCache(std::size_t capacity_bytes) : capacity_bytes_(capacity_bytes) {}

  // The prepared rig `id`, running `prepare` (outside the lock) when absent.
  // A failed preparation is not cached; waiting callers get the same error.
  core::Result<CacheLookup> get(const std::string& id, const std::function<core::Result<core::PreparedRig>()>& prepare);
  void erase(const std::string& id);  // rig deleted
  CacheStats stats() const;

 private:
  using Outcome = core::Result<PreparedRigPtr>;
  struct Entry {
    std::shared_future<Outcome> ready;
    std::size_t bytes = 0;                       // 0 while preparing
    std::list<std::string>::iterator lru;        // position in lru_ (front = most recent)
  };
  void evictLocked();

  const std::size_t capacity_bytes_;
  mutable std::mutex mutex_;
  std::map<std::string, Entry> entries_;
  std::list<std::string> lru_;
  std::size_t bytes_ = 0;
  std::int64_t hits_ = 0, misses_ = 0, evictions_ = 0;
};

}  // namespace server
