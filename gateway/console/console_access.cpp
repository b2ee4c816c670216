#include "gateway/console/console_access.hpp"

#include <openssl/evp.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <fstream>
#include <sstream>

namespace fieldgate {

std::string sha256_hex(std::string_view text) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
  unsigned int length = 0;
  EVP_Digest(text.data(), text.size(), digest.data(), &length, EVP_sha256(), nullptr);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (unsigned int i = 0; i < length; ++i) {
    out += kHex[digest[i] >> 4];
    out += kHex[digest[i] & 0x0f];
  }
  return out;
}

std::optional<std::string> read_token_hash(const std::string& path, std::string& error) {
  std::ifstream in(path);
  if (!in) {
    error = "cannot read '" + path + "'";
    return std::nullopt;
  }
  std::stringstream text;
  text << in.rdbuf();
  std::string first, second, more;
  text >> first >> second >> more;
  std::transform(first.begin(), first.end(), first.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool hex = first.size() == 64 && std::all_of(first.begin(), first.end(), [](char c) {
                     return std::isxdigit(static_cast<unsigned char>(c));
                   });
  if (!hex || !more.empty() || (!second.empty() && second != "-")) {
    error = "'" + path +
            "' must hold the SHA-256 of the token as 64 hex digits (printf %s TOKEN | sha256sum)";
    return std::nullopt;
  }
  return first;
}

std::string_view to_string(ConsoleAccess access) {
  // In the order of the enumeration.
  static constexpr std::string_view kText[] = {"allowed", "address not on the console's allow list",
                                               "no token", "wrong token"};
  return kText[static_cast<std::size_t>(access)];
}

ConsoleAccess check_console_access(const ConsoleConfig& config, const asio::ip::address& peer,
                                   std::optional<std::string_view> token) {
  asio::ip::address from = peer;
  if (peer.is_v6() && peer.to_v6().is_v4_mapped())
    from = asio::ip::make_address_v4(asio::ip::v4_mapped, peer.to_v6());
  if (!config.allow.empty() && !config.allow.allows(from)) return ConsoleAccess::address_refused;
  if (config.token_sha256.empty()) return ConsoleAccess::allowed;
  if (!token) return ConsoleAccess::token_missing;
  // Both sides are digests of the same length: comparing them leaks nothing about the token.
  const std::string offered = sha256_hex(*token);
  unsigned char differ = 0;
  for (std::size_t i = 0; i < offered.size(); ++i)
    differ |= static_cast<unsigned char>(offered[i] ^ config.token_sha256[i]);
  return differ == 0 ? ConsoleAccess::allowed : ConsoleAccess::token_wrong;
}

namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string percent_decoded(std::string_view text) {
  std::string out;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '%' && i + 2 < text.size()) {
      const int hi = hex_value(text[i + 1]), lo = hex_value(text[i + 2]);
      if (hi >= 0 && lo >= 0) {
        out += static_cast<char>(hi * 16 + lo);
        i += 2;
        continue;
      }
    }
    out += text[i] == '+' ? ' ' : text[i];
  }
  return out;
}

}  // namespace

std::optional<std::string> query_parameter(std::string_view target, std::string_view key) {
  const auto query = target.find('?');
  if (query == std::string_view::npos) return std::nullopt;
  std::string_view rest = target.substr(query + 1);
  while (!rest.empty()) {
    const auto amp = rest.find('&');
    const std::string_view pair = rest.substr(0, amp);
    if (pair.size() > key.size() && pair.starts_with(key) && pair[key.size()] == '=')
      return percent_decoded(pair.substr(key.size() + 1));
    if (amp == std::string_view::npos) break;
    rest.remove_prefix(amp + 1);
  }
  return std::nullopt;
}

std::optional<std::string> request_token(std::string_view authorization, std::string_view target) {
  constexpr std::string_view kBearer = "Bearer ";
  if (authorization.starts_with(kBearer)) return std::string(authorization.substr(kBearer.size()));
  return query_parameter(target, "token");
}

}  // namespace fieldgate
