#pragma once

#include <boost/asio/ip/address.hpp>

#include <optional>
#include <string>
#include <string_view>

#include "gateway/config/gateway_config.hpp"

namespace fieldgate {

// SHA-256 of `text`, lower-case hex.
std::string sha256_hex(std::string_view text);

// The console's token file: the SHA-256 of the access token as hex, as `sha256sum` prints it
// (its first field; a trailing " -" and newline are allowed). nullopt, with the reason in
// `error`, if the file cannot be read or holds anything else.
std::optional<std::string> read_token_hash(const std::string& path, std::string& error);

enum class ConsoleAccess { allowed, address_refused, token_missing, token_wrong };
std::string_view to_string(ConsoleAccess access);

// Whether a request may see the console: from an address on the allow list (when there is
// one), with the token whose hash the configuration holds (when it holds one).
ConsoleAccess check_console_access(const ConsoleConfig& config, const asio::ip::address& peer,
                                   std::optional<std::string_view> token);

// The value of `key` in the target's query, percent-decoded; nullopt if it is not there.
std::optional<std::string> query_parameter(std::string_view target, std::string_view key);

// The token a request carries: `Authorization: Bearer TOKEN`, else `token=` in the query (an
// EventSource cannot set headers).
std::optional<std::string> request_token(std::string_view authorization, std::string_view target);

}  // namespace fieldgate
