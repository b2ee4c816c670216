#pragma once

#include <boost/asio/ip/address.hpp>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate {

namespace asio = boost::asio;

// One allow-list entry: an address with a prefix length, IPv4 or IPv6 ("10.0.0.0/8",
// "fd00::/8", "192.168.1.20" meaning /32).
class Cidr {
 public:
  static std::optional<Cidr> parse(std::string_view text, std::string& error);
  bool contains(const asio::ip::address& address) const;
  std::string to_string() const;

 private:
  asio::ip::address network_;
  unsigned prefix_ = 0;
};

// Empty list: every client is allowed.
class ClientAllowList {
 public:
  ClientAllowList() = default;
  explicit ClientAllowList(std::vector<Cidr> entries) : entries_(std::move(entries)) {}
  bool allows(const asio::ip::address& address) const;
  bool empty() const { return entries_.empty(); }

 private:
  std::vector<Cidr> entries_;
};

}  // namespace fieldgate
