#include "server/auth.h"

#include <cctype>
#include <fstream>
#include <sstream>
#include <string_view>

#include <openssl/crypto.h>
#include <openssl/evp.h>

namespace server {

namespace {

// Keys are compared as SHA-256 digests: every comparison then takes the same
// time whatever the presented key's length (a byte-wise compare of keys of
// different lengths returned at once, telling the length).
ApiKeys::Digest digestOf(const std::string& key) {
  ApiKeys::Digest digest{};
  unsigned int length = 0;
  EVP_Digest(key.data(), key.size(), digest.data(), &length, EVP_sha256(), nullptr);
  return digest;
}

core::Status addKey(std::map<std::string, std::string>& tenants, const std::string& key, const std::string& tenant,
                    const std::string& where) {
  if (key.empty() || tenant.empty()) return core::makeError(core::ErrorCode::kInvalidArgument, where + ": expected '<key> <tenant>'");
  if (!tenants.emplace(key, tenant).second) {
    return core::makeError(core::ErrorCode::kInvalidArgument, where + ": API key given twice");
  }
  return core::Ok{};
}

}  // namespace

ApiKeys ApiKeys::disabled() { return ApiKeys{}; }

core::Result<ApiKeys> ApiKeys::load(const std::filesystem::path& file, const std::string& env_value) {
  ApiKeys keys;
  keys.enabled_ = true;
  if (!file.empty()) {
    std::ifstream in(file);
    if (!in) return core::makeError(core::ErrorCode::kIo, file.string() + ": cannot open API key file");
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      if (const auto hash = line.find('#'); hash != std::string::npos) line.resize(hash);
      std::istringstream fields(line);
      std::string key, tenant, extra;
      if (!(fields >> key)) continue;  // blank or comment
      fields >> tenant;
      const std::string where = file.string() + ":" + std::to_string(n);
      if (fields >> extra) return core::makeError(core::ErrorCode::kInvalidArgument, where + ": expected '<key> <tenant>'");
      if (auto ok = addKey(keys.tenants_, key, tenant, where); !ok) return ok.error();
    }
  }
  std::istringstream entries(env_value);
  std::string entry;
  while (std::getline(entries, entry, ',')) {
    if (entry.empty()) continue;
    const auto colon = entry.find(':');
    const std::string key = colon == std::string::npos ? entry : entry.substr(0, colon);
    const std::string tenant = colon == std::string::npos ? "" : entry.substr(colon + 1);
    if (auto ok = addKey(keys.tenants_, key, tenant, "RIGPORT_API_KEYS entry '" + key.substr(0, 4) + "...'"); !ok) {
      return ok.error();
    }
  }
  if (keys.tenants_.empty()) {
    return core::makeError(core::ErrorCode::kInvalidArgument,
                           "no API keys configured (" + (file.empty() ? std::string("RIGPORT_API_KEYS is empty") : file.string() + " has no keys") +
                               "); run with --no-auth for local use");
  }
  for (const auto& [key, tenant] : keys.tenants_) keys.digests_.emplace_back(digestOf(key), tenant);
  return keys;
}

std::optional<std::string> ApiKeys::tenantFor(const std::string& header) const {
  if (!enabled_) return std::string();
  // "Bearer <key>": the scheme in any case, then one or more spaces (RFC 9110
  // sec. 11.1 and 11.4).
  constexpr std::string_view kScheme = "bearer";
  if (header.size() <= kScheme.size() || header[kScheme.size()] != ' ') return std::nullopt;
  for (std::size_t i = 0; i < kScheme.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(header[i])) != kScheme[i]) return std::nullopt;
  }
  const std::size_t start = header.find_first_not_of(' ', kScheme.size());
  if (start == std::string::npos) return std::nullopt;
  const Digest presented = digestOf(header.substr(start));
  std::optional<std::string> tenant;
  for (const auto& [digest, t] : digests_) {  // visit every key: timing does not reveal which matched
    if (CRYPTO_memcmp(digest.data(), presented.data(), digest.size()) == 0) tenant = t;
  }
  return tenant;
}

int AuthFailureLimit::blockedFor(const std::string& client) {
  if (max_per_minute_ <= 0) return 0;
  std::lock_guard lock(mutex_);
  const auto it = by_client_.find(client);
  if (it == by_client_.end()) return 0;
  const auto left = it->second.blocked_until - Clock::now();
  if (left <= Clock::duration::zero()) return 0;
  return static_cast<int>(std::chrono::ceil<std::chrono::seconds>(left).count());
}

bool AuthFailureLimit::recordFailure(const std::string& client) {
  if (max_per_minute_ <= 0) return false;
  std::lock_guard lock(mutex_);
  const auto now = Clock::now();
  if (by_client_.size() > 10000) forgetOld(now);
  Failures& f = by_client_[client];
  f.times.push_back(now);
  while (!f.times.empty() && now - f.times.front() > std::chrono::minutes(1)) f.times.pop_front();
  if (static_cast<int>(f.times.size()) <= max_per_minute_) return false;
  const bool starts = f.blocked_until <= now;
  f.blocked_until = now + std::chrono::minutes(1);
  return starts;
}

void AuthFailureLimit::forgetOld(Clock::time_point now) {
  for (auto it = by_client_.begin(); it != by_client_.end();) {
    const bool quiet = it->second.times.empty() || now - it->second.times.back() > std::chrono::minutes(1);
    it = quiet && it->second.blocked_until <= now ? by_client_.erase(it) : std::next(it);
  }
}

}  // namespace server
