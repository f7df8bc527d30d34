// Wall-clock times as the service stores (epoch milliseconds) and shows them
// (RFC 3339 UTC with milliseconds).
#pragma once

#include <cstdint>
#include <string>

namespace server {

std::int64_t nowMs();
std::string formatTimestamp(std::int64_t epoch_ms);  // "" for 0

}  // namespace server
