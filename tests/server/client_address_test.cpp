// The client behind a request (server/client_address.h): X-Forwarded-For is
// believed only from trusted proxies, read from the right, and what a client
// writes itself never names it.
#include "server/client_address.h"

#include <gtest/gtest.h>

namespace rigport_test {
namespace {

server::TrustedProxies trusted(const std::vector<std::string>& entries) {
  auto proxies = server::TrustedProxies::parse(entries);
  EXPECT_TRUE(proxies.ok()) << proxies.error().message;
  return proxies.ok() ? *proxies : server::TrustedProxies();
}

TEST(TrustedProxies, AddressesAndBlocksOfBothFamilies) {
  const auto proxies = trusted({"192.0.2.10", "10.0.0.0/8", "172.16.0.0/12", "fd00::/8", "::1"});
  EXPECT_TRUE(proxies.trusts("192.0.2.10"));
  EXPECT_FALSE(proxies.trusts("192.0.2.11"));
  EXPECT_TRUE(proxies.trusts("10.255.0.1"));
  EXPECT_FALSE(proxies.trusts("11.0.0.1"));
  EXPECT_TRUE(proxies.trusts("172.31.255.255"));  // a prefix that is not whole bytes
  EXPECT_FALSE(proxies.trusts("172.32.0.1"));
  EXPECT_TRUE(proxies.trusts("fd12:3456::1"));
  EXPECT_FALSE(proxies.trusts("fe80::1"));
  EXPECT_TRUE(proxies.trusts("::1"));
  EXPECT_TRUE(proxies.trusts("::ffff:10.1.2.3"));  // an IPv4 client on a dual-stack socket
  EXPECT_FALSE(proxies.trusts("not-an-address"));
  EXPECT_FALSE(trusted({}).trusts("127.0.0.1"));
  EXPECT_TRUE(trusted({"0.0.0.0/0"}).trusts("203.0.113.5"));
  EXPECT_FALSE(trusted({"0.0.0.0/0"}).trusts("2001:db8::1"));
}

TEST(TrustedProxies, TheClientIsTheFirstUntrustedHopFromTheRight) {
  const auto proxies = trusted({"10.0.0.0/8"});
  // Not from a trusted peer: the header is the client's own words.
  EXPECT_EQ(proxies.clientOf("203.0.113.5", "198.51.100.1"), "203.0.113.5");
  // From a trusted peer: its hops are skipped, then the first other address.
  EXPECT_EQ(proxies.clientOf("10.0.0.2", "203.0.113.5"), "203.0.113.5");
  EXPECT_EQ(proxies.clientOf("10.0.0.2", "198.51.100.1, 203.0.113.5, 10.0.0.9"), "203.0.113.5");
  EXPECT_EQ(proxies.clientOf("10.0.0.2", " 203.0.113.5 ,10.0.0.9 "), "203.0.113.5");
  EXPECT_EQ(proxies.clientOf("10.0.0.2", "2001:db8::7"), "2001:db8::7");
  // No header, or only trusted hops: the leftmost trusted address known.
  EXPECT_EQ(proxies.clientOf("10.0.0.2", ""), "10.0.0.2");
  EXPECT_EQ(proxies.clientOf("10.0.0.2", "10.0.0.7, 10.0.0.9"), "10.0.0.7");
  // Something no proxy writes (a name, a port, garbage): the last trusted hop, not the text.
  EXPECT_EQ(proxies.clientOf("10.0.0.2", "evil, 10.0.0.9"), "10.0.0.9");
  EXPECT_EQ(proxies.clientOf("10.0.0.2", "203.0.113.5:4711"), "10.0.0.2");
  EXPECT_EQ(proxies.clientOf("10.0.0.2", ",,"), "10.0.0.2");
  // Without trusted proxies the peer is always the client.
  EXPECT_EQ(trusted({}).clientOf("10.0.0.2", "203.0.113.5"), "10.0.0.2");
}

TEST(TrustedProxies, AMalformedEntryIsNamed) {
  for (const std::string bad : {"nginx", "10.0.0.0/33", "10.0.0.0/", "10.0.0.0/-1", "fd00::/129", "10.0.0.0/8x", ""}) {
    auto proxies = server::TrustedProxies::parse({"127.0.0.1", bad});
    ASSERT_FALSE(proxies.ok()) << bad;
    EXPECT_NE(proxies.error().message.find("--trusted-proxy \"" + bad + "\""), std::string::npos)
        << proxies.error().message;
  }
}

}  // namespace
}  // namespace rigport_test
