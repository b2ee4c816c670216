#include <gtest/gtest.h>

#include <string>
#include <vector>

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

struct Containment {
  const char* cidr;
  const char* address;
  bool contains;
};

void expect_containment(const std::vector<Containment>& cases) {
  for (const Containment& c : cases) {
    SCOPED_TRACE(std::string(c.cidr) + " contains " + c.address);
    EXPECT_EQ(cidr(c.cidr).contains(ip(c.address)), c.contains);
  }
}

TEST(Cidr, Ipv4Prefixes) {
  expect_containment({
      {"10.0.0.0/8", "10.200.3.4", true},
      {"10.0.0.0/8", "11.0.0.1", false},
      {"192.168.1.20", "192.168.1.20", true},
      {"192.168.1.20", "192.168.1.21", false},
      {"0.0.0.0/0", "8.8.8.8", true},
      {"172.16.0.0/12", "172.31.255.255", true},
      {"172.16.0.0/12", "172.32.0.0", false},
  });
}

TEST(Cidr, Ipv6AndMappedIpv4) {
  expect_containment({
      {"fd00::/8", "fd12:3456::1", true},
      {"fd00::/8", "fe80::1", false},
      {"::1/128", "::1", true},
      // A dual-stack listener sees IPv4 clients as ::ffff:a.b.c.d.
      {"127.0.0.0/8", "::ffff:127.0.0.1", true},
      {"::1/128", "127.0.0.1", false},
  });
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
