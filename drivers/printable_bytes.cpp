#include "drivers/printable_bytes.hpp"

#include <fmt/format.h>

namespace fieldgate {

std::string printable_bytes(std::string_view bytes, std::size_t limit) {
  std::string out;
  for (const char c : bytes.substr(0, limit)) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '\r')
      out += "\\r";
    else if (c == '\n')
      out += "\\n";
    else if (u < 0x20 || u >= 0x7f || c == '\\' || c == '\'')
      out += fmt::format("\\x{:02x}", u);
    else
      out += c;
  }
  if (bytes.size() > limit) out += "...";
  return out;
}

}  // namespace fieldgate
