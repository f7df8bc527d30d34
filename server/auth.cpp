#include "server/auth.h"

#include <fstream>
#include <sstream>

namespace server {

namespace {

bool constantTimeEqual(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff |= static_cast<unsigned char>(a[i] ^ b[i]);
  return diff == 0;
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
  return keys;
}

std::optional<std::string> ApiKeys::tenantFor(const std::string& header) const {
  if (!enabled_) return std::string();
  constexpr std::string_view kBearer = "Bearer ";
  if (header.size() <= kBearer.size() || header.compare(0, kBearer.size(), kBearer) != 0) return std::nullopt;
  const std::string key = header.substr(kBearer.size());
  std::optional<std::string> tenant;
  for (const auto& [k, t] : tenants_) {  // visit every key: timing does not reveal which matched
    if (constantTimeEqual(k, key)) tenant = t;
  }
  return tenant;
}

}  // namespace server
