// The blob-collection lock: deleting a blob no row references must not race
// a writer that is about to reference it (blobs are content-addressed, so a
// new job or rig may reuse the bytes of one being deleted). Writers (uploads,
// workers) hold it shared from writing a blob until their row is committed;
// the collector (DELETE of a job, the retention sweep) holds it exclusive
// while it checks references and deletes. In one process an in-process
// shared mutex is enough; replicas sharing a store and a blob volume also
// take the store's lock (PostgreSQL: a session advisory lock), so a
// collector on one replica waits for writers on all of them.
// Meets the SharedMutex requirements (std::shared_lock, std::unique_lock).
#pragma once

#include <set>
#include <shared_mutex>
#include <string>

#include "server/store.h"

namespace server {

class BlobCollection {
 public:
  explicit BlobCollection(MetadataStore& store) : store_(store) {}
  BlobCollection(const BlobCollection&) = delete;
  BlobCollection& operator=(const BlobCollection&) = delete;

  void lock();
  void unlock();
  void lock_shared();
  void unlock_shared();
  // Under lock(): deletes each of `hashes` that no rig or job row
  // references; returns how many went. Deletes nothing when the store's lock
  // could not be taken (a blob left behind costs space, a blob deleted under
  // a writer loses its data).
  int removeUnreferenced(BlobStore& blobs, const std::set<std::string>& hashes);
  // Under lock(): whether the store's lock is held too. A caller about to
  // delete a row whose blobs it will collect checks this first: a row deleted
  // without its blobs collected would leave them with no one to find them.
  bool mayCollect() const { return exclusive_in_store_; }

 private:
  MetadataStore& store_;
  std::shared_mutex mutex_;
  bool exclusive_in_store_ = false;  // written and read under the exclusive lock
};

}  // namespace server
