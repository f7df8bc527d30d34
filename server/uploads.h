// Multipart uploads streamed to spool files under <data-dir>/uploads, so a
// large body is never held in memory twice; each part's bytes go to its own
// file and are later adopted by the blob store (same filesystem: a rename).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <variant>

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
std::variant<SpooledUpload, api::Problem> spoolMultipart(const httplib::Request& request,
                                                         const httplib::ContentReader& reader,
                                                         const std::filesystem::path& spool_dir,
                                                         std::uint64_t max_body_bytes);

}  // namespace server
