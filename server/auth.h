// API keys -> tenants. Keys come from a file ("<key> <tenant>" per line, #
// comments) and/or the environment (RIGPORT_API_KEYS="key:tenant,key:tenant").
// With auth off every request is the tenant "".
#pragma once

#include <array>
#include <chrono>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <unordered_map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/base/error.h"

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

// Failed authentications per client address: past `max_per_minute` in the
// last minute, the address is refused (429 auth-throttled, every request that
// needs a key) until a minute after its last counted failure, so keys cannot
// be guessed at speed. 0 turns it off. Behind a load balancer the client is
// the one its X-Forwarded-For names when it is a trusted proxy
// (server/client_address.h); otherwise every client has its address.
class AuthFailureLimit {
 public:
  explicit AuthFailureLimit(int max_per_minute) : max_per_minute_(max_per_minute) {}
  // Seconds until `client` may try again; 0 when it may now.
  int blockedFor(const std::string& client);
  // Counts a failure; true when this one starts the client's block.
  bool recordFailure(const std::string& client);

 private:
  using Clock = std::chrono::steady_clock;
  struct Failures {
    std::deque<Clock::time_point> times;  // within the last minute
    Clock::time_point blocked_until{};
  };
  void forgetOld(Clock::time_point now);  // bounds the map under address churn
  const int max_per_minute_;
  std::mutex mutex_;
  std::unordered_map<std::string, Failures> by_client_;
};

}  // namespace server
