#include "can_frame.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace fieldgate::sim::canopen {

CanFrame CanFrame::make(std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
  CanFrame frame;
  frame.id = id;
  frame.len = static_cast<std::uint8_t>(std::min<std::size_t>(bytes.size(), 8));
  std::copy_n(bytes.begin(), frame.len, frame.data.begin());
  return frame;
}

CanFrame CanFrame::remote(std::uint32_t id) {
  CanFrame frame;
  frame.id = id;
  frame.rtr = true;
  return frame;
}

std::string to_string(const CanFrame& frame) {
  std::string text = fmt::format("{:03X}#", frame.id);
  if (frame.rtr) return text + "R";
  for (std::size_t i = 0; i < frame.len; ++i) text += fmt::format("{:02X}", frame.data[i]);
  return text;
}

namespace {
int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}
}  // namespace

std::optional<CanFrame> parse_frame(std::string_view text) {
  const auto hash = text.find('#');
  if (hash == std::string_view::npos || hash == 0 || hash > 3) return std::nullopt;
  CanFrame frame;
  for (char c : text.substr(0, hash)) {
    const int d = hex_digit(c);
    if (d < 0) return std::nullopt;
    frame.id = frame.id * 16 + static_cast<std::uint32_t>(d);
  }
  if (frame.id > 0x7FF) return std::nullopt;
  auto payload = text.substr(hash + 1);
  if (payload == "R" || payload == "r") {
    frame.rtr = true;
    return frame;
  }
  std::string digits;
  for (char c : payload)
    if (c != '.') digits += c;
  if (digits.size() % 2 != 0 || digits.size() > 16) return std::nullopt;
  for (std::size_t i = 0; i < digits.size(); i += 2) {
    const int hi = hex_digit(digits[i]);
    const int lo = hex_digit(digits[i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    frame.data[frame.len++] = static_cast<std::uint8_t>(hi * 16 + lo);
  }
  return frame;
}

}  // namespace fieldgate::sim::canopen
