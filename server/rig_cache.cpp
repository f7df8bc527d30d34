#include "server/rig_cache.h"

namespace server {

core::Result<CacheLookup> RigCache::get(const std::string& id,
                                        const std::function<core::Result<core::PreparedRig>()>& prepare) {
  std::unique_lock lock(mutex_);
  if (auto it = entries_.find(id); it != entries_.end()) {
    lru_.splice(lru_.begin(), lru_, it->second.lru);
    ++hits_;
    std::shared_future<Outcome> ready = it->second.ready;
    lock.unlock();
    const Outcome& outcome = ready.get();  // waits while another caller prepares
    if (!outcome) return outcome.error();
    return CacheLookup{*outcome, true};
  }
  ++misses_;
  std::promise<Outcome> promise;
  lru_.push_front(id);
  entries_[id] = Entry{promise.get_future().share(), 0, lru_.begin()};
  lock.unlock();

  auto prepared = prepare();  // outside the lock: other rigs are served meanwhile
  Outcome outcome = prepared ? Outcome(std::make_shared<const core::PreparedRig>(std::move(*prepared)))
                             : Outcome(prepared.error());
  promise.set_value(outcome);

  lock.lock();
  if (auto it = entries_.find(id); it != entries_.end()) {
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
  return CacheLookup{*outcome, false};
}

void RigCache::evictLocked() {
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

void RigCache::erase(const std::string& id) {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(id);
  if (it == entries_.end() || it->second.bytes == 0) return;
  bytes_ -= it->second.bytes;
  lru_.erase(it->second.lru);
  entries_.erase(it);
}

CacheStats RigCache::stats() const {
  std::lock_guard lock(mutex_);
  return CacheStats{static_cast<std::int64_t>(bytes_), static_cast<std::int64_t>(capacity_bytes_),
                    static_cast<std::int64_t>(entries_.size()), hits_, misses_, evictions_};
}

}  // namespace server
