#include "drivers/copley_ascii/copley_codec.hpp"

#include <fmt/format.h>

#include <cctype>
#include <charconv>
#include <cstdlib>

namespace fieldgate::copley {

std::string encode_command(int node, char axis, std::string_view command) {
  std::string out;
  if (node != 0) out += std::to_string(node);
  if (axis != 0) {
    out += '.';
    out += axis;
  }
  if (!out.empty()) out += ' ';
  out += command;
  out += '\r';
  return out;
}

std::size_t frame_length(std::string_view buf) {
  const auto cr = buf.find('\r');
  return cr == std::string_view::npos ? 0 : cr + 1;
}

namespace {

// Decimal or 0x-hex integers, possibly negative, separated by exactly one space (every
// transcript of the guide); false on anything else.
bool parse_numbers(std::string_view text, std::vector<int64_t>& out) {
  while (true) {
    const auto end = text.find(' ');
    std::string_view token = text.substr(0, end);
    bool negative = false;
    if (!token.empty() && token.front() == '-') {
      negative = true;
      token.remove_prefix(1);
    }
    int base = 10;
    if (token.size() > 2 && token[0] == '0' && token[1] == 'x') {
      base = 16;
      token.remove_prefix(2);
    }
    if (token.empty()) return false;
    uint64_t magnitude = 0;
    const auto [p, ec] =
        std::from_chars(token.data(), token.data() + token.size(), magnitude, base);
    if (ec != std::errc{} || p != token.data() + token.size() ||
        magnitude > static_cast<uint64_t>(INT64_MAX))
      return false;
    const auto v = static_cast<int64_t>(magnitude);
    out.push_back(negative ? -v : v);
    if (end == std::string_view::npos) return true;
    text = text.substr(end + 1);
  }
}

// The line without its CR and a stray LF on either side (LF is no part of the protocol, but an
// adapter may add one); nothing else is trimmed.
std::string_view without_line_end(std::string_view line) {
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  if (!line.empty() && line.back() == '\n') line.remove_suffix(1);
  if (!line.empty() && line.front() == '\n') line.remove_prefix(1);
  return line;
}

}  // namespace

ParsedReply parse_reply(std::string_view line) {
  ParsedReply reply;
  line = without_line_end(line);
  if (line == "ok") {
    reply.kind = ParsedReply::Kind::ok;
    return reply;
  }
  if (line.size() < 2) return reply;
  const char tag = line.front();
  const std::string_view rest = line.substr(1);
  if (tag != 'v' && tag != 'r' && tag != 'e') return reply;
  // `v 1200` or `v1200` (§2.8): one space at most after the tag.
  const std::string_view numbers = rest.front() == ' ' ? rest.substr(1) : rest;
  if (!parse_numbers(numbers, reply.values)) {
    reply.values.clear();
    return reply;
  }
  if (tag == 'v') {
    reply.kind = ParsedReply::Kind::values;
  } else if (reply.values.size() != 1) {
    reply.values.clear();
  } else {
    reply.kind = tag == 'r' ? ParsedReply::Kind::register_value : ParsedReply::Kind::error;
  }
  return reply;
}

ExpectedReply expected_reply(std::string_view command) {
  ExpectedReply e;
  if (command.size() < 1 || (command.size() > 1 && command[1] != ' ')) return e;
  std::vector<std::string_view> tokens;
  for (std::string_view rest = command.substr(1); !rest.empty();) {
    while (!rest.empty() && rest.front() == ' ') rest.remove_prefix(1);
    const auto end = rest.find(' ');
    if (!rest.empty()) tokens.push_back(rest.substr(0, end));
    rest = end == std::string_view::npos ? std::string_view{} : rest.substr(end);
  }
  switch (command.front()) {
    case 's':
    case 'c':
    case 't':
      e.kind = ExpectedReply::Kind::ok;
      return e;
    case 'r':
      e.kind = ExpectedReply::Kind::none;
      return e;
    case 'i':
      e.kind = tokens.size() > 1 ? ExpectedReply::Kind::ok : ExpectedReply::Kind::register_value;
      return e;
    case 'g': {
      e.kind = ExpectedReply::Kind::values;
      e.count = 1;
      if (tokens.empty() || tokens[0].size() < 2) return e;
      const std::string id(tokens[0].substr(1));  // after the bank letter
      char* end = nullptr;
      const long v = std::strtol(id.c_str(), &end, 0);
      if (end == id.c_str() || *end != '\0') return e;
      // Multi-value variables (digest §4): 0x6b nine values, 0x70-0x77 two, 0x5f "multi-value"
      // without a count.
      if (v == 0x6b) e.count = 9;
      if (v >= 0x70 && v <= 0x77) e.count = 2;
      if (v == 0x5f) e.count = 0;
      return e;
    }
    default:
      return e;
  }
}

std::string_view error_text(int64_t code) {
  switch (code) {
    case 1:
      return "Too much data passed with command";
    case 3:
      return "Unknown command code";
    case 4:
      return "Not enough data was supplied with the command";
    case 5:
      return "Too much data was supplied with the command";
    case 9:
      return "Unknown variable ID";
    case 10:
      return "Data value out of range";
    case 11:
      return "Attempt to modify read-only variable";
    case 14:
      return "Unknown axis state";
    case 15:
      return "Variable doesn't exist on requested page";
    case 18:
      return "Illegal attempt to start a move while currently moving";
    case 19:
      return "Illegal velocity limit for move";
    case 20:
      return "Illegal acceleration limit for move";
    case 21:
      return "Illegal deceleration limit for move";
    case 22:
      return "Illegal jerk limit for move";
    case 25:
      return "Invalid trajectory mode";
    case 27:
      return "Command is not allowed while CVM is running";
    case 31:
      return "Invalid node ID for serial port forwarding";
    case 32:
      return "CAN Network communications failure";
    case 33:
      return "ASCII command parsing error";
    default:
      return "unknown error code";
  }
}

std::optional<Address> parse_address(std::string_view text, std::string& error) {
  Address a;
  const auto dot = text.find('.');
  const std::string_view node_text = text.substr(0, dot);
  if (!node_text.empty()) {
    int node = -1;
    const auto [p, ec] =
        std::from_chars(node_text.data(), node_text.data() + node_text.size(), node);
    if (ec != std::errc{} || p != node_text.data() + node_text.size() || node < 0 || node > 127) {
      error = fmt::format("Copley node ID must be 0..127, found '{}'", node_text);
      return std::nullopt;
    }
    a.node = node;
  }
  if (dot != std::string_view::npos) {
    const auto axis = text.substr(dot + 1);
    if (axis.size() != 1 || axis[0] < 'a' || axis[0] > 'c') {
      error = fmt::format("Copley axis must be a, b or c, found '{}'", axis);
      return std::nullopt;
    }
    a.axis = axis[0];
  }
  if (node_text.empty() && dot == std::string_view::npos) {
    error = "empty Copley node address";
    return std::nullopt;
  }
  return a;
}

}  // namespace fieldgate::copley
