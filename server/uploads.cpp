#include "server/uploads.h"

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <system_error>

#include "api/error_codes.h"
#include "api/json.h"

namespace server {

SpooledUpload::~SpooledUpload() {
  for (const auto& [field, part] : parts) {
    std::error_code ec;
    std::filesystem::remove(part.path, ec);  // adopted files are already gone
  }
}

std::variant<SpooledUpload, api::Problem> spoolMultipart(const httplib::Request& request,
                                                         const httplib::ContentReader& reader,
                                                         const std::filesystem::path& spool_dir,
                                                         std::uint64_t max_body_bytes) {
  static std::atomic<unsigned long long> counter{0};
  if (!request.is_multipart_form_data()) {
    return api::makeProblem(api::WireError::kUnsupportedMediaType,
                            "expected Content-Type multipart/form-data, got '" + request.get_header_value("Content-Type") + "'",
                            request.path);
  }
  const auto tooLarge = [&] {
    return api::makeProblem(api::WireError::kPayloadTooLarge,
                            "request body over the limit of " + std::to_string(max_body_bytes) + " bytes", request.path);
  };
  if (request.has_header("Content-Length") &&
      std::strtoull(request.get_header_value("Content-Length").c_str(), nullptr, 10) > max_body_bytes) {
    return tooLarge();
  }
  SpooledUpload upload;
  std::uint64_t received = 0;
  std::FILE* current = nullptr;
  SpooledPart* part = nullptr;
  std::string problem;
  bool spool_failed = false;  // a write to the spool dir failed: storage, not the client
  auto closeCurrent = [&] {
    // fclose flushes: its failure (a full disk) means a truncated part.
    if (current && std::fclose(current) != 0) spool_failed = true;
    current = nullptr;
  };
  const bool ok = reader(
      [&](const httplib::MultipartFormData& header) {
        closeCurrent();
        // Names end up in the store, in listings and in messages: a client's
        // bytes must be text (UTF-8), said here naming the field.
        if (!api::isValidUtf8(header.name)) {
          problem = "a multipart field name is not valid UTF-8";
          return false;
        }
        if (!api::isValidUtf8(header.filename)) {
          problem = "the file name of multipart field '" + header.name + "' is not valid UTF-8";
          return false;
        }
        if (upload.parts.count(header.name)) {
          problem = "multipart field '" + header.name + "' given twice";
          return false;
        }
        SpooledPart& p = upload.parts[header.name];
        p.filename = header.filename;
        p.path = spool_dir / ("upload-" + std::to_string(counter.fetch_add(1)) + ".part");
        current = std::fopen(p.path.c_str(), "wb");
        if (!current) {
          spool_failed = true;
          return false;
        }
        part = &p;
        return true;
      },
      [&](const char* data, std::size_t length) {
        if (!current) {
          problem = "multipart data before any part header";
          return false;
        }
        if (std::fwrite(data, 1, length, current) != length) {
          spool_failed = true;
          return false;
        }
        part->size += length;
        received += length;
        return received <= max_body_bytes;
      });
  closeCurrent();
  if (spool_failed) {
    return api::makeProblem(api::WireError::kStorageUnavailable,
                            "the upload could not be spooled: the service's storage does not take writes now; retry later",
                            request.path);
  }
  if (!problem.empty()) return api::makeProblem(api::WireError::kMalformedRequest, problem, request.path);
  if (received > max_body_bytes) return tooLarge();
  if (!ok) return api::makeProblem(api::WireError::kMalformedRequest, "the multipart body could not be read", request.path);
  return upload;
}

}  // namespace server
