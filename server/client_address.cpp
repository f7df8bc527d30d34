#include "server/client_address.h"

#include <arpa/inet.h>

#include <cstring>
#include <optional>
#include <string_view>

#include "core/base/text.h"

namespace server {
namespace {

// An address as 16 bytes, IPv4 mapped into IPv6 (::ffff:a.b.c.d), so one
// block matches a client however its address is written.
std::optional<std::array<unsigned char, 16>> parseAddress(const std::string& text) {
  std::array<unsigned char, 16> out{};
  in_addr v4{};
  if (inet_pton(AF_INET, text.c_str(), &v4) == 1) {
    out[10] = out[11] = 0xff;
    std::memcpy(out.data() + 12, &v4, 4);
    return out;
  }
  in6_addr v6{};
  if (inet_pton(AF_INET6, text.c_str(), &v6) == 1) {
    std::memcpy(out.data(), &v6, 16);
    return out;
  }
  return std::nullopt;
}

bool isMappedV4(const std::array<unsigned char, 16>& a) {
  for (int i = 0; i < 10; ++i) {
    if (a[static_cast<std::size_t>(i)] != 0) return false;
  }
  return a[10] == 0xff && a[11] == 0xff;
}

}  // namespace

core::Result<TrustedProxies> TrustedProxies::parse(const std::vector<std::string>& entries) {
  TrustedProxies out;
  for (const std::string& entry : entries) {
    auto fail = [&](const std::string& why) {
      return core::makeError(core::ErrorCode::kInvalidArgument, "--trusted-proxy \"" + entry + "\": " + why);
    };
    const std::size_t slash = entry.find('/');
    const auto address = parseAddress(entry.substr(0, slash));
    if (!address) return fail("not an IPv4 or IPv6 address (or CIDR block such as 10.0.0.0/8)");
    Block block;
    block.address = *address;
    if (slash != std::string::npos) {
      const std::string bits = entry.substr(slash + 1);
      const int limit = isMappedV4(*address) ? 32 : 128;
      if (bits.empty() || bits.size() > 3 || bits.find_first_not_of("0123456789") != std::string::npos ||
          std::stoi(bits) > limit) {
        return fail("the prefix length must be 0-" + std::to_string(limit));
      }
      block.prefix_bits = std::stoi(bits) + (limit == 32 ? 96 : 0);
    }
    out.blocks_.push_back(block);
  }
  return out;
}

bool TrustedProxies::trusts(const std::string& address) const {
  const auto parsed = parseAddress(address);
  if (!parsed) return false;
  for (const Block& block : blocks_) {
    const int whole = block.prefix_bits / 8, rest = block.prefix_bits % 8;
    if (std::memcmp(parsed->data(), block.address.data(), static_cast<std::size_t>(whole)) != 0) continue;
    if (rest > 0) {
      const auto mask = static_cast<unsigned char>(0xff << (8 - rest));
      if (((*parsed)[static_cast<std::size_t>(whole)] & mask) != (block.address[static_cast<std::size_t>(whole)] & mask)) {
        continue;
      }
    }
    return true;
  }
  return false;
}

std::string TrustedProxies::clientOf(const std::string& peer, const std::string& forwarded_for) const {
  if (blocks_.empty() || !trusts(peer)) return peer;
  std::string client = peer;
  std::size_t end = forwarded_for.size();
  while (end > 0) {
    const std::size_t comma = forwarded_for.rfind(',', end - 1);
    const std::size_t begin = comma == std::string::npos ? 0 : comma + 1;
    const std::string hop(core::trim(std::string_view(forwarded_for).substr(begin, end - begin)));
    // Something a trusted proxy would not write: the last trusted hop is all we know.
    if (!parseAddress(hop)) return client;
    client = hop;
    if (!trusts(hop)) return client;
    if (comma == std::string::npos) break;
    end = comma;
  }
  return client;
}

}  // namespace server
