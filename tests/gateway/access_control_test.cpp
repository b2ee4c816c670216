#include <gtest/gtest.h>

#include "gateway/modbus/access_control.hpp"

namespace fieldgate {
namespace {

Cidr cidr(const char* text) {
  std::string error;
  auto c = Cidr::parse(text, error);
  EXPECT_TRUE(c) << text << ": " << error;
  return *c;
}

asio::ip::address ip(const char* text) {
  return asio::ip::make_address(text);
}

TEST(Cidr, Ipv4Prefixes) {
  EXPECT_TRUE(cidr("10.0.0.0/8").contains(ip("10.200.3.4")));
  EXPECT_FALSE(cidr("10.0.0.0/8").contains(ip("11.0.0.1")));
  EXPECT_TRUE(cidr("192.168.1.20").contains(ip("192.168.1.20")));
  EXPECT_FALSE(cidr("192.168.1.20").contains(ip("192.168.1.21")));
  EXPECT_TRUE(cidr("0.0.0.0/0").contains(ip("8.8.8.8")));
  EXPECT_TRUE(cidr("172.16.0.0/12").contains(ip("172.31.255.255")));
  EXPECT_FALSE(cidr("172.16.0.0/12").contains(ip("172.32.0.0")));
}

TEST(Cidr, Ipv6AndMappedIpv4) {
  EXPECT_TRUE(cidr("fd00::/8").contains(ip("fd12:3456::1")));
  EXPECT_FALSE(cidr("fd00::/8").contains(ip("fe80::1")));
  EXPECT_TRUE(cidr("::1/128").contains(ip("::1")));
  // A dual-stack listener sees IPv4 clients as ::ffff:a.b.c.d.
  EXPECT_TRUE(cidr("127.0.0.0/8").contains(ip("::ffff:127.0.0.1")));
  EXPECT_FALSE(cidr("::1/128").contains(ip("127.0.0.1")));
}

TEST(Cidr, RejectsBadText) {
  std::string error;
  EXPECT_FALSE(Cidr::parse("10.0.0.0/33", error));
  EXPECT_NE(error.find("0..32"), std::string::npos);
  EXPECT_FALSE(Cidr::parse("fd00::/129", error));
  EXPECT_FALSE(Cidr::parse("plc-1/24", error));
  EXPECT_NE(error.find("not an IPv4 or IPv6 address"), std::string::npos);
  EXPECT_FALSE(Cidr::parse("10.0.0.0/x", error));
}

TEST(ClientAllowList, EmptyAllowsAll) {
  EXPECT_TRUE(ClientAllowList{}.allows(ip("203.0.113.9")));
  ClientAllowList list({cidr("10.0.0.0/8"), cidr("fd00::/8")});
  EXPECT_TRUE(list.allows(ip("10.1.1.1")));
  EXPECT_TRUE(list.allows(ip("fd00::5")));
  EXPECT_FALSE(list.allows(ip("127.0.0.1")));
}

}  // namespace
}  // namespace fieldgate
