// Immutable products of source-only work, keyed by tenant and content:
// prepared rigs (parsed rig, TPS factorisations, surface index, dense
// centres) by rig id, and marker distance fields by (mesh, markers, method).
// The tenant is part of every key (tenantCacheKey), so a job's cache_hit
// never tells one tenant that another used the same bytes, and one tenant's
// delete never evicts another's entry. Bounded by bytes,
// least recently used first out. Concurrent jobs on one key prepare it once:
// the first caller runs the preparation, the others wait for its result (no
// thundering herd). Entries are shared; eviction only drops the cache's
// reference.
#pragma once

#include <cstdint>
#include <functional>
#include <future>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "core/base/error.h"
#include "core/fit/fit.h"
#include "core/retarget/retarget.h"
#include "core/transfer/transfer.h"
#include "server/metrics.h"

namespace server {

// The cache key of `content_key` for `tenant`.
inline std::string tenantCacheKey(const std::string& tenant, const std::string& content_key) {
  return std::to_string(tenant.size()) + ":" + tenant + "/" + content_key;  // length-prefixed: no tenant name collides
}

// T: an immutable value with `std::size_t memoryBytes() const`.
template <typename T>
class PreparedCache {
 public:
  using Ptr = std::shared_ptr<const T>;
  struct Lookup {
    Ptr value;
    bool hit = false;  // true: no source-only work was done for this caller
  };

  explicit PreparedCache(std::size_t capacity_bytes) : capacity_bytes_(capacity_bytes) {}

  // The value for `key`, running `prepare` (outside the lock) when absent. A
  // failed preparation is not cached; callers waiting on it get the same error.
  core::Result<Lookup> get(const std::string& key, const std::function<core::Result<T>()>& prepare) {
    std::unique_lock lock(mutex_);
    if (auto it = entries_.find(key); it != entries_.end()) {
      lru_.splice(lru_.begin(), lru_, it->second.lru);
      ++hits_;
      std::shared_future<Outcome> ready = it->second.ready;
      lock.unlock();
      const Outcome& outcome = ready.get();  // waits while another caller prepares
      if (!outcome) return outcome.error();
      return Lookup{*outcome, true};
    }
    ++misses_;
    std::promise<Outcome> promise;
    lru_.push_front(key);
    entries_[key] = Entry{promise.get_future().share(), 0, lru_.begin()};
    lock.unlock();

    auto prepared = prepare();  // outside the lock: other keys are served meanwhile
    Outcome outcome = prepared ? Outcome(std::make_shared<const T>(std::move(*prepared))) : Outcome(prepared.error());
    promise.set_value(outcome);

    lock.lock();
    if (auto it = entries_.find(key); it != entries_.end()) {
      if (!outcome) {
        lru_.erase(it->second.lru);
        entries_.erase(it);
      } else {
        it->second.bytes = (*outcome)->memoryBytes();
        bytes_ += it->second.bytes;
        evictLocked();
      }
    }
    if (!outcome) return outcome.error();
    return Lookup{*outcome, false};
  }

  void erase(const std::string& key) {
    std::lock_guard lock(mutex_);
    auto it = entries_.find(key);
    if (it == entries_.end() || it->second.bytes == 0) return;  // absent, or being prepared
    bytes_ -= it->second.bytes;
    lru_.erase(it->second.lru);
    entries_.erase(it);
  }

  CacheStats stats() const {
    std::lock_guard lock(mutex_);
    return CacheStats{static_cast<std::int64_t>(bytes_), static_cast<std::int64_t>(capacity_bytes_),
                      static_cast<std::int64_t>(entries_.size()), hits_, misses_, evictions_};
  }

 private:
  using Outcome = core::Result<Ptr>;
  struct Entry {
    std::shared_future<Outcome> ready;
    std::size_t bytes = 0;                  // 0 while preparing
    std::list<std::string>::iterator lru;   // position in lru_ (front = most recent)
  };

  void evictLocked() {
    // Least recently used first; entries still being prepared (bytes 0) stay.
    auto it = lru_.end();
    while (bytes_ > capacity_bytes_ && it != lru_.begin()) {
      --it;
      auto entry = entries_.find(*it);
      if (entry->second.bytes == 0) continue;
      bytes_ -= entry->second.bytes;
      ++evictions_;
      entries_.erase(entry);
      it = lru_.erase(it);
    }
  }

  const std::size_t capacity_bytes_;
  mutable std::mutex mutex_;
  std::map<std::string, Entry> entries_;
  std::list<std::string> lru_;
  std::size_t bytes_ = 0;
  std::int64_t hits_ = 0, misses_ = 0, evictions_ = 0;
};

using RigCache = PreparedCache<core::PreparedRig>;
using DistanceCache = PreparedCache<core::MarkerDistances>;
using FitCache = PreparedCache<core::FitReference>;

// The service's caches share one byte budget: 5/8 for prepared rigs (the hot
// path of transfer jobs, and what a fit reference is built on), 1/8 for fit
// references (their own part: Laplacians, lip pairs, the search's index),
// 1/4 for marker distance fields (retarget jobs).
struct Caches {
  explicit Caches(std::size_t capacity_bytes)
      : rigs(capacity_bytes / 8 * 5), fits(capacity_bytes / 8), distances(capacity_bytes / 4) {}
  RigCache rigs;
  FitCache fits;
  DistanceCache distances;
};

}  // namespace server
