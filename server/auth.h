// API keys -> tenants. Keys come from a file ("<key> <tenant>" per line, #
// comments) and/or the environment (RIGPORT_API_KEYS="key:tenant,key:tenant").
// With auth off every request is the tenant "".
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>

#include "core/error.h"

namespace server {

class ApiKeys {
 public:
  static ApiKeys disabled();
  // Reads `file` (may be empty) and `env_value` (may be empty); error names the
  // file and line of a malformed entry or a key given twice.
  static core::Result<ApiKeys> load(const std::filesystem::path& file, const std::string& env_value);

  bool enabled() const { return enabled_; }
  // Tenant of an `Authorization: Bearer <key>` header value; nullopt when the
  // key is missing or unknown. Comparison is constant-time per key.
  std::optional<std::string> tenantFor(const std::string& authorization_header) const;
  std::size_t size() const { return tenants_.size(); }

 private:
  bool enabled_ = false;
  std::map<std::string, std::string> tenants_;  // key -> tenant
};

}  // namespace server
