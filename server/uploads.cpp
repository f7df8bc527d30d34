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

api::Result<SpooledUpload> spoolMultipart(const httplib::Request& request,
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

UploadSlots::UploadSlots(int total, int per_tenant, int per_client)
    : total_(total), per_tenant_(per_tenant), per_client_(per_client) {}

UploadSlots::Ticket::Ticket(UploadSlots* slots, std::string tenant, std::string client)
    : slots_(slots), tenant_(std::move(tenant)), client_(std::move(client)) {}

UploadSlots::Ticket::Ticket(Ticket&& other) noexcept
    : slots_(other.slots_), tenant_(std::move(other.tenant_)), client_(std::move(other.client_)) {
  other.slots_ = nullptr;
}

UploadSlots::Ticket::~Ticket() {
  if (slots_) slots_->release(tenant_, client_);
}

rigport::Result<UploadSlots::Ticket, std::string> UploadSlots::acquire(const std::string& tenant, const std::string& client) {
  std::lock_guard lock(mutex_);
  if (by_tenant_[tenant] >= per_tenant_) {
    return "this tenant already has " + std::to_string(per_tenant_) + " uploads in progress (the limit per tenant)";
  }
  if (by_client_[client] >= per_client_) {
    return "this client address already has " + std::to_string(per_client_) + " uploads in progress (the limit per address)";
  }
  if (in_progress_ >= total_) return "the service has " + std::to_string(total_) + " uploads in progress (its limit)";
  ++in_progress_;
  ++by_tenant_[tenant];
  ++by_client_[client];
  return Ticket(this, tenant, client);
}

void UploadSlots::release(const std::string& tenant, const std::string& client) {
  std::lock_guard lock(mutex_);
  --in_progress_;
  if (--by_tenant_[tenant] <= 0) by_tenant_.erase(tenant);
  if (--by_client_[client] <= 0) by_client_.erase(client);
}

}  // namespace server
