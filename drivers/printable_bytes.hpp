#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace fieldgate {

// Bytes from a field link for a log line or an error text: CR and LF as \r and \n, other control
// characters and non-ASCII as \xNN. Longer input than `limit` is cut and ends with "...".
std::string printable_bytes(std::string_view bytes, std::size_t limit = std::string_view::npos);

}  // namespace fieldgate
