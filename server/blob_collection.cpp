#include "server/blob_collection.h"

namespace server {

void BlobCollection::lock() {
  mutex_.lock();
  exclusive_in_store_ = store_.lockBlobCollection(/*exclusive=*/true).ok();
}

void BlobCollection::unlock() {
  if (exclusive_in_store_) store_.unlockBlobCollection(/*exclusive=*/true);
  exclusive_in_store_ = false;
  mutex_.unlock();
}

int BlobCollection::removeUnreferenced(BlobStore& blobs, const std::set<std::string>& hashes) {
  if (!exclusive_in_store_) return 0;
  int removed = 0;
  for (const std::string& hash : hashes) {
    if (hash.empty() || store_.blobReferenced(hash)) continue;
    blobs.remove(hash);
    ++removed;
  }
  return removed;
}

void BlobCollection::lock_shared() {
  mutex_.lock_shared();
  // Not held (the store is away): the writer goes on; its row write then
  // fails too, or lands while no collector elsewhere could check references.
  (void)store_.lockBlobCollection(/*exclusive=*/false);
}

void BlobCollection::unlock_shared() {
  store_.unlockBlobCollection(/*exclusive=*/false);
  mutex_.unlock_shared();
}

}  // namespace server
