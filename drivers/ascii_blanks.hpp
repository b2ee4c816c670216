#pragma once

#include <string_view>

namespace fieldgate {

// Space, tab, CR or LF: what the ASCII families' replies may carry around their fields.
constexpr bool is_ascii_blank(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n';
}

// `s` without its leading and trailing blanks (is_ascii_blank).
constexpr std::string_view trim_blanks(std::string_view s) {
  while (!s.empty() && is_ascii_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_ascii_blank(s.back())) s.remove_suffix(1);
  return s;
}

}  // namespace fieldgate
