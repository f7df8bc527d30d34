// The address of the client behind a request. Behind a load balancer (nginx
// in docker/compose.yaml) every connection comes from the balancer, so the
// per-client limits (failed authentications, uploads) and the access log
// would see one client; a balancer named trusted (`--trusted-proxy`, an
// address or a CIDR block) passes the real one in X-Forwarded-For.
//
// The header is read from the right (each proxy appends the address it was
// connected from): entries of trusted proxies are skipped, and the first
// other one is the client. What a client writes itself stays to the left of
// what the trusted proxies appended, so it cannot pose as another address.
// A peer that is not trusted is the client, whatever it sends.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "core/base/error.h"

namespace server {

class TrustedProxies {
 public:
  // Each entry an IPv4 or IPv6 address, or a CIDR block ("10.0.0.0/8",
  // "fd00::/8"); the error names the entry at fault.
  static core::Result<TrustedProxies> parse(const std::vector<std::string>& entries);

  bool empty() const { return blocks_.empty(); }
  bool trusts(const std::string& address) const;
  // The client of a request from `peer` carrying `forwarded_for` (the
  // X-Forwarded-For values, comma-separated; empty when absent).
  std::string clientOf(const std::string& peer, const std::string& forwarded_for) const;

 private:
  struct Block {
    std::array<unsigned char, 16> address{};  // IPv4 as IPv4-mapped IPv6
    int prefix_bits = 128;
  };
  std::vector<Block> blocks_;
};

}  // namespace server
