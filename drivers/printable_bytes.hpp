#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace fieldgate {

// Bytes from a field link for a log line or an error text: CR and LF as \r and \n, other control
// characters, non-ASCII, the backslash and the single quote as \xNN (so an escape is never
// ambiguous, and the wire trace's quoted bytes end at the next quote). Longer input than `limit` is
// cut and ends with "...".
std::string printable_bytes(std::string_view bytes, std::size_t limit = std::string_view::npos);

}  // namespace fieldgate
