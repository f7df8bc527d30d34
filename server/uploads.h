// Multipart uploads streamed to spool files under <data-dir>/uploads, so a
// large body is never held in memory twice; each part's bytes go to its own
// file and are later adopted by the blob store (same filesystem: a rename).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>

#include "api/http.h"

#include "api/types.h"

namespace server {

struct SpooledPart {
  std::string filename;            // as sent by the client (may be empty)
  std::filesystem::path path;      // spool file
  std::uint64_t size = 0;
};

// Owns the spool files of one request and removes what was not adopted.
class SpooledUpload {
 public:
  SpooledUpload() = default;
  SpooledUpload(const SpooledUpload&) = delete;
  SpooledUpload& operator=(const SpooledUpload&) = delete;
  SpooledUpload(SpooledUpload&&) = default;
  ~SpooledUpload();
  std::map<std::string, SpooledPart> parts;  // by field name (a field sent twice is an error)
};

// Reads a multipart/form-data body into spool files. Problems: 415 when the
// body is not multipart, 413 over `max_body_bytes`, 400 for a field given
// twice or a broken body.
api::Result<SpooledUpload> spoolMultipart(const httplib::Request& request,
                                                         const httplib::ContentReader& reader,
                                                         const std::filesystem::path& spool_dir,
                                                         std::uint64_t max_body_bytes);

// Upload slots: a multipart body being received holds one slot of the
// service's, one of its tenant's and one of its client address's, so a
// tenant or an address trickling uploads blocks only itself.
class UploadSlots {
 public:
  UploadSlots(int total, int per_tenant, int per_client);
  // Held while the upload is received and checked; released when destroyed.
  class Ticket {
   public:
    Ticket(UploadSlots* slots, std::string tenant, std::string client);
    Ticket(Ticket&& other) noexcept;
    Ticket& operator=(Ticket&&) = delete;
    Ticket(const Ticket&) = delete;
    ~Ticket();

   private:
    UploadSlots* slots_;
    std::string tenant_, client_;
  };
  // A ticket, or which limit is reached (a sentence for the 429).
  rigport::Result<Ticket, std::string> acquire(const std::string& tenant, const std::string& client);

 private:
  void release(const std::string& tenant, const std::string& client);
  const int total_, per_tenant_, per_client_;
  std::mutex mutex_;
  int in_progress_ = 0;
  std::map<std::string, int> by_tenant_, by_client_;
};

}  // namespace server
