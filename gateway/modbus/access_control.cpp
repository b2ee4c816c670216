#include "gateway/modbus/access_control.hpp"

#include <charconv>

namespace fieldgate {

std::optional<Cidr> Cidr::parse(std::string_view text, std::string& error) {
  const auto slash = text.find('/');
  const std::string address_text(text.substr(0, slash));
  boost::system::error_code ec;
  Cidr c;
  c.network_ = asio::ip::make_address(address_text, ec);
  if (ec) {
    error = "'" + address_text + "' is not an IPv4 or IPv6 address";
    return std::nullopt;
  }
  const unsigned max = c.network_.is_v4() ? 32 : 128;
  c.prefix_ = max;
  if (slash != std::string_view::npos) {
    const auto p = text.substr(slash + 1);
    unsigned value = 0;
    const auto [end, perr] = std::from_chars(p.data(), p.data() + p.size(), value);
    if (perr != std::errc{} || end != p.data() + p.size() || value > max) {
      error = "prefix length '" + std::string(p) + "' must be 0.." + std::to_string(max);
      return std::nullopt;
    }
    c.prefix_ = value;
  }
  return c;
}

namespace {
template <typename Bytes>
bool prefix_equal(const Bytes& a, const Bytes& b, unsigned prefix) {
  for (unsigned bit = 0; bit < prefix; ++bit) {
    const unsigned byte = bit / 8, mask = 0x80u >> (bit % 8);
    if ((a[byte] & mask) != (b[byte] & mask)) return false;
  }
  return true;
}
}  // namespace

bool Cidr::contains(const asio::ip::address& address) const {
  asio::ip::address a = address;
  if (a.is_v6() && a.to_v6().is_v4_mapped())
    a = asio::ip::make_address_v4(asio::ip::v4_mapped, a.to_v6());
  if (a.is_v4() != network_.is_v4()) return false;
  if (a.is_v4()) return prefix_equal(a.to_v4().to_bytes(), network_.to_v4().to_bytes(), prefix_);
  return prefix_equal(a.to_v6().to_bytes(), network_.to_v6().to_bytes(), prefix_);
}

std::string Cidr::to_string() const {
  return network_.to_string() + "/" + std::to_string(prefix_);
}

bool ClientAllowList::allows(const asio::ip::address& address) const {
  if (entries_.empty()) return true;
  for (const auto& e : entries_)
    if (e.contains(address)) return true;
  return false;
}

}  // namespace fieldgate
