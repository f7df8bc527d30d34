// API keys -> tenants. Keys come from a file ("<key> <tenant>" per line, #
// comments) and/or the environment (RIGPORT_API_KEYS="key:tenant,key:tenant").
// With auth off every request is the tenant "".
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"

namespace server {

class ApiKeys {
 public:
  static ApiKeys disabled();
  // Reads `file` (may be empty) and `env_value` (may be empty); error names the
  // file and line of a malformed entry or a key given twice.
  static core::Result<ApiKeys> load(const std::filesystem::path& file, const std::string& env_value);

  using Digest = std::array<unsigned char, 32>;  // SHA-256

  bool enabled() const { return enabled_; }
  // Tenant of an `Authorization: Bearer <key>` header value (the scheme in
  // any case); nullopt when the key is missing or unknown. Keys are compared
  // by their SHA-256 digests, each in constant time, every key visited.
  std::optional<std::string> tenantFor(const std::string& authorization_header) const;
  std::size_t size() const { return tenants_.size(); }

 private:
  bool enabled_ = false;
  std::map<std::string, std::string> tenants_;            // key -> tenant (loading: duplicates refused)
  std::vector<std::pair<Digest, std::string>> digests_;   // what requests are compared with
};

}  // namespace server
