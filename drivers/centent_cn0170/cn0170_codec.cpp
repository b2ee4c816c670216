#include "drivers/centent_cn0170/cn0170_codec.hpp"

#include <fmt/format.h>

#include <cctype>
#include <charconv>
#include <cmath>

#include "drivers/ascii_blanks.hpp"

namespace fieldgate::cn0170 {

namespace {

std::string upper(std::string_view s) {
  std::string out(s);
  for (auto& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

// Replies carry spaces and their CR/LF around the text (digest §5), nothing else: a tab is no
// character the manual prints.
std::string_view trim_line(std::string_view s) {
  const auto begin = s.find_first_not_of(" \r\n");
  if (begin == std::string_view::npos) return {};
  return s.substr(begin, s.find_last_not_of(" \r\n") - begin + 1);
}

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

bool is_hex(char c) {
  return is_digit(c) || (c >= 'A' && c <= 'F');
}

// "  0D485h": optional spaces, 1–9 hex digits, h (or H, §5). The manual prints the digits in
// upper case only: a lower-case digit is a garbled character, not a hex digit. Values above 32
// bits are refused: no CN0170 register is wider.
std::optional<int64_t> hex_value(std::string_view s) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  if (s.size() < 2 || (s.back() != 'h' && s.back() != 'H')) return std::nullopt;
  s.remove_suffix(1);
  if (s.empty() || s.size() > 9) return std::nullopt;
  for (char c : s)
    if (!is_hex(c)) return std::nullopt;
  uint64_t v = 0;
  std::from_chars(s.data(), s.data() + s.size(), v, 16);
  if (v > 0xffffffffu) return std::nullopt;
  return static_cast<int64_t>(v);
}

std::optional<int> small_decimal(std::string_view s) {
  if (s.empty() || s.size() > 3) return std::nullopt;
  int v = 0;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc{} || p != s.data() + s.size()) return std::nullopt;
  return v;
}

bool two_digits(std::string_view s, std::size_t at, int64_t& out) {
  if (at + 2 > s.size() || !is_digit(s[at]) || !is_digit(s[at + 1])) return false;
  out = (s[at] - '0') * 10 + (s[at + 1] - '0');
  return true;
}

// "08:45.11" or "02/15/97"
bool clock_reading(std::string_view s, char first, char second, std::vector<int64_t>& values) {
  if (s.size() != 8 || s[2] != first || s[5] != second) return false;
  int64_t a = 0, b = 0, c = 0;
  if (!two_digits(s, 0, a) || !two_digits(s, 3, b) || !two_digits(s, 6, c)) return false;
  values = {a, b, c};
  return true;
}

// The line without its unit prefix. Replies are matched as the manual prints them: letters in
// upper case, the hex suffix h (or H).
Message parse_body(std::string_view s) {
  Message m;
  const auto value = [&](MessageKind kind, std::string key, std::string_view hex_part,
                         int64_t max) {
    if (auto v = hex_value(hex_part); v && *v <= max) {
      m.kind = kind;
      m.key = std::move(key);
      m.values = {*v};
    }
  };
  if (s.empty()) return m;
  if (s == "Q*") {
    m.kind = MessageKind::queue_full;
    return m;
  }
  if (s == "*Q" || s == "Q") {
    m.kind = MessageKind::queue_empty;
    return m;
  }
  if (s.size() == 2 && (s[0] == 'X' || s[0] == 'Y') && (s[1] == 'P' || s[1] == 'V')) {
    m.kind = s[1] == 'P' ? MessageKind::position_trigger : MessageKind::velocity_trigger;
    m.key = std::string(1, s[0]);
    return m;
  }
  if (s.front() == '"') {
    // "<string>" ? — the string itself may contain anything but its closing quote.
    const auto close = s.rfind('"');
    if (close == 0) return m;
    const std::string_view tail = trim_line(s.substr(close + 1));
    if (tail != "?") return m;
    m.kind = MessageKind::reject;
    m.text = std::string(s.substr(1, close - 1));
    return m;
  }
  if (s.size() == 4 && s[0] == '[' && s[1] == 'U' && is_digit(s[2]) && s[3] == ']') {
    m.kind = MessageKind::unit_list;
    m.subject = s[2] - '0';
    return m;
  }
  if (s.size() == 2 && s[0] == 'U' && is_digit(s[1])) {
    m.kind = MessageKind::autobaud;
    m.subject = s[1] - '0';
    return m;
  }
  if (s.size() == 2 && s[0] == 'M' && s[1] >= '1' && s[1] <= '3') {
    m.kind = MessageKind::mode;
    m.key = "M";
    m.values = {s[1] - '0'};
    return m;
  }
  if (clock_reading(s, ':', '.', m.values)) {
    m.kind = MessageKind::time;
    m.key = "T";
    return m;
  }
  if (clock_reading(s, '/', '/', m.values)) {
    m.kind = MessageKind::date;
    m.key = "D";
    return m;
  }
  if (s.rfind("XYV=", 0) == 0) {
    value(MessageKind::velocity, "XYV", s.substr(4), 0xffff);
    return m;
  }
  if (s[0] == 'X' || s[0] == 'Y') {
    const std::string axis(1, s[0]);
    std::string_view rest = s.substr(1);
    if (rest.size() >= 3 && rest[0] == '/' && (rest[1] == 'X' || rest[1] == 'Y') &&
        rest[1] != s[0] && rest[2] == '=') {
      value(MessageKind::ratio, axis + "/" + rest[1], rest.substr(3), 0xffffffff);
      return m;
    }
    if (rest.size() >= 2 && rest[1] == '=') {
      if (rest[0] == 'V') value(MessageKind::velocity, axis + "V", rest.substr(2), 0xffff);
      if (rest[0] == 'A') value(MessageKind::acceleration, axis + "A", rest.substr(2), 0xffff);
      if (rest[0] == 'C') {
        const std::string_view c = rest.substr(2);
        std::optional<int> n;
        if (c == "L") n = 17;
        if (c == "P") n = 18;
        if (c == "U") n = 19;
        if (!n && c.size() <= 2) n = small_decimal(c);  // 1-16 as printed
        if (n && *n >= 1 && *n <= 19) {
          m.kind = MessageKind::profile;
          m.key = axis + "C";
          m.values = {*n};
        }
      }
      if (m.kind != MessageKind::unknown) return m;
    }
    // Position: X=…h (p.35) or XP=…h (p.2); '+'/'-' instead of '=' while moving.
    if (!rest.empty() && rest[0] == 'P') rest.remove_prefix(1);
    if (!rest.empty() && (rest[0] == '=' || rest[0] == '+' || rest[0] == '-')) {
      if (auto v = hex_value(rest.substr(1))) {
        m.kind = MessageKind::position;
        m.key = axis + "P";
        int64_t status = 0;
        if (rest[0] != '=') {
          const bool x = s[0] == 'X';
          status = kMoving | (x ? kXMoving : kYMoving);
          if (rest[0] == '-') status |= x ? kXCounterClockwise : kYCounterClockwise;
        }
        m.values = {*v, status};
      }
    }
    return m;
  }
  if (s[0] == 'P') {
    if (s.size() == 4 && s[1] >= '1' && s[1] <= '4' && s[2] == '=' &&
        (s[3] == '0' || s[3] == '1')) {
      m.kind = MessageKind::io;
      m.key = std::string(s.substr(0, 2));
      m.values = {s[3] - '0'};
      return m;
    }
    if (s.size() >= 2 && s[1] == '=') value(MessageKind::aux, "P", s.substr(2), 0xff);
    return m;
  }
  if (s[0] == 'A') {
    std::string_view rest = s.substr(1);
    std::string key = "A";
    if (!rest.empty() && rest[0] == '\\') {
      key += '\\';
      rest.remove_prefix(1);
    }
    if (rest.size() >= 2 && rest[1] == '=' &&
        ((key.size() == 2 && (rest[0] == 'X' || rest[0] == 'Y')) ||
         (key.size() == 1 && (rest[0] == '1' || rest[0] == '2')))) {
      value(MessageKind::analog, key + rest[0], rest.substr(2), 0xff);
    }
    return m;
  }
  return m;
}

}  // namespace

std::optional<int> parse_unit_address(std::string_view text, std::string& error) {
  const std::string_view t = trim_blanks(text);
  if (t.size() != 1 || !is_digit(t[0])) {
    error = fmt::format("CN0170 unit number must be one digit 0..9, found '{}'", text);
    return std::nullopt;
  }
  return t[0] - '0';
}

std::string encode_select(int unit) {
  return fmt::format(".U{}\r", unit);
}

std::size_t frame_length(std::string_view buf) {
  const auto end = buf.find_first_of("\r\n");
  return end == std::string_view::npos ? 0 : end + 1;
}

std::vector<std::string> split_instructions(std::string_view request) {
  std::vector<std::string> out;
  std::size_t begin = 0;
  while (begin <= request.size()) {
    const auto end = request.find(';', begin);
    const auto part =
        trim_blanks(request.substr(begin, end == std::string_view::npos ? end : end - begin));
    if (!part.empty()) out.emplace_back(part);
    if (end == std::string_view::npos) break;
    begin = end + 1;
  }
  return out;
}

std::string_view to_string(MessageKind kind) {
  switch (kind) {
    case MessageKind::blank:
      return "blank line";
    case MessageKind::position:
      return "position";
    case MessageKind::velocity:
      return "velocity";
    case MessageKind::acceleration:
      return "acceleration";
    case MessageKind::profile:
      return "profile";
    case MessageKind::ratio:
      return "ratio";
    case MessageKind::io:
      return "I/O bit";
    case MessageKind::aux:
      return "aux port";
    case MessageKind::analog:
      return "analog input";
    case MessageKind::mode:
      return "mode";
    case MessageKind::time:
      return "time";
    case MessageKind::date:
      return "date";
    case MessageKind::unit_list:
      return "unit list";
    case MessageKind::autobaud:
      return "reset (auto-baud)";
    case MessageKind::reject:
      return "rejected string";
    case MessageKind::queue_full:
      return "queue nearly full";
    case MessageKind::queue_empty:
      return "queue empty";
    case MessageKind::position_trigger:
      return "move done";
    case MessageKind::velocity_trigger:
      return "max velocity";
    case MessageKind::unknown:
      return "unknown";
  }
  return "?";
}

Message parse_message(std::string_view line) {
  const std::string_view t = trim_line(line);
  Message m;
  if (t.empty()) {
    m.kind = MessageKind::blank;
    return m;
  }
  m = parse_body(t);
  if (m.kind != MessageKind::unknown) return m;
  if (t[0] >= '1' && t[0] <= '9') {
    std::size_t skip = 1;
    if (t.size() > 1 && (t[1] == ' ' || t[1] == ':')) skip = 2;
    m = parse_body(t.substr(skip));
    if (m.kind != MessageKind::unknown) {
      m.unit = t[0] - '0';
      m.prefixed = true;
      return m;
    }
  }
  m = Message{};
  m.text = std::string(t);
  return m;
}

std::optional<Query> classify_query(std::string_view instruction) {
  std::string s;
  for (char c : upper(instruction))
    if (c != ' ') s += c;
  if (s.size() < 2 || s.back() != '?') return std::nullopt;
  s.pop_back();
  Query q;
  if (s == "XP" || s == "YP") {
    q = {MessageKind::position, s, 2, true};
  } else if (s == "XV" || s == "YV" || s == "XYV") {
    q = {MessageKind::velocity, s, 1, true};
  } else if (s == "XA" || s == "YA") {
    q = {MessageKind::acceleration, s, 1, true};
  } else if (s == "XC" || s == "YC") {
    q = {MessageKind::profile, s, 1, false};
  } else if (s == "Y/X" || s == "X/Y") {
    q = {MessageKind::ratio, s, 1, true};
  } else if (s.size() == 2 && s[0] == 'P' && s[1] >= '1' && s[1] <= '4') {
    q = {MessageKind::io, s, 1, false};
  } else if (s == "P") {
    q = {MessageKind::aux, s, 1, true};
  } else if (s == "A\\X" || s == "A\\Y" || s == "A1" || s == "A2") {
    q = {MessageKind::analog, s, 1, true};
  } else if (s == "M") {
    q = {MessageKind::mode, s, 1, false};
  } else if (s == "T") {
    q = {MessageKind::time, s, 3, false};
  } else if (s == "D") {
    q = {MessageKind::date, s, 3, false};
  } else {
    return std::nullopt;
  }
  return q;
}

bool starts_reply(std::string_view partial, int unit, const Query& query) {
  std::string_view s = partial;
  while (!s.empty() && (s.front() == '\r' || s.front() == '\n' || s.front() == ' '))
    s.remove_prefix(1);
  int sender = 0;
  if (!s.empty() && s.front() >= '1' && s.front() <= '9') {
    sender = s.front() - '0';
    s.remove_prefix(1);
    if (!s.empty() && (s.front() == ' ' || s.front() == ':')) s.remove_prefix(1);
  }
  if (sender != unit) return false;
  const std::string u = upper(s);
  if (query.kind == MessageKind::position) {
    // X=…h, X+…h, X-…h (p.35) or XP=…h (p.2).
    const char axis = query.key.front();
    return u.size() >= 2 && u[0] == axis &&
           (u[1] == '=' || u[1] == '+' || u[1] == '-' || (u.size() >= 3 && u.substr(1, 2) == "P="));
  }
  if (query.kind == MessageKind::mode) return u == "M";
  return u.size() > query.key.size() && u.compare(0, query.key.size(), query.key) == 0 &&
         u[query.key.size()] == '=';
}

int values_of_request(const std::vector<Query>& queries) {
  int n = 0;
  bool position = false;
  for (const auto& q : queries) {
    n += q.value_count;
    position = position || q.kind == MessageKind::position;
  }
  return n + (position ? 1 : 0);
}

InstructionKind classify_instruction(std::string_view instruction) {
  std::string s;
  for (char c : upper(instruction))
    if (c != ' ') s += c;
  if (!s.empty() && s[0] == '.')
    return s.find('=') != std::string::npos ? InstructionKind::unit_assignment
                                            : InstructionKind::unit_command;
  if (classify_query(s)) return InstructionKind::query;
  if (s == "K") return InstructionKind::kill;
  if (s == "Q") return InstructionKind::quit;
  if (s == "H") return InstructionKind::halt;
  if (s == "M1") return InstructionKind::mode_immediate;
  if (s == "M2") return InstructionKind::mode_program;
  if (s == "M3") return InstructionKind::mode_operate;
  return InstructionKind::other;
}

namespace {

bool is_axis(char c) {
  return c == 'X' || c == 'Y' || c == 'x' || c == 'y';
}

// X+-5 -> X-5 and X+0FFFFFC00H -> X-0400H: a relative distance rendered from a signed
// setpoint. Speed control (X++), ratio enable (Y/X+) and the like have no number after the '+'.
std::string signed_relative_distances(std::string s) {
  for (std::size_t i = 0; i + 2 < s.size(); ++i) {
    if (!is_axis(s[i]) || s[i + 1] != '+') continue;
    if (i > 0 && s[i - 1] == '/') continue;
    const char next = s[i + 2];
    if (next == '-' && i + 3 < s.size() && (is_digit(s[i + 3]) || s[i + 3] == '.')) {
      s.erase(i + 1, 1);
      continue;
    }
    if (!is_digit(next)) continue;
    std::size_t end = i + 2;
    while (end < s.size() && (is_digit(s[end]) || (s[end] >= 'A' && s[end] <= 'F'))) ++end;
    if (end >= s.size() || s[end] != 'H') continue;
    const std::string_view digits(s.data() + i + 2, end - (i + 2));
    if (digits.size() > 9) continue;
    uint64_t v = 0;
    std::from_chars(digits.data(), digits.data() + digits.size(), v, 16);
    if (v < 0x80000000u || v > 0xffffffffu) continue;
    const std::string magnitude = fmt::format("0{:X}", (uint64_t{1} << 32) - v);
    s.replace(i + 1, end - (i + 1), "-" + magnitude);
  }
  return s;
}

// The first absolute position (X=n, XP=n, also inside linked and interpolated forms) below 0:
// a decimal with a minus sign, or raw hex of 2^31 and more (a negative int32 target rendered as
// hex). The position register "accepts only positive signed numbers" (Set Position, p.35) and
// X=n moves CW when n is greater than the register (p.21): 0FFFFD800H is not 10 steps CCW of
// 0 but a run CW towards 4,194,294 full steps. Ratio (Y/X=) and analog (A\X) keys are skipped.
std::optional<std::string> negative_absolute_position(const std::string& u) {
  for (std::size_t i = 0; i < u.size(); ++i) {
    if (!is_axis(u[i]) || (i > 0 && (u[i - 1] == '/' || u[i - 1] == '\\'))) continue;
    std::size_t j = i + 1;
    if (j < u.size() && u[j] == 'P') ++j;
    if (j >= u.size() || u[j] != '=') continue;
    ++j;
    while (j < u.size() && u[j] == ' ') ++j;
    const std::size_t start = j;
    if (j < u.size() && u[j] == '-') {
      std::size_t end = j + 1;
      while (end < u.size() && (is_digit(u[end]) || u[end] == '.')) ++end;
      if (end > j + 1) return u.substr(i, end - i);
      continue;
    }
    while (j < u.size() && (is_digit(u[j]) || (u[j] >= 'A' && u[j] <= 'F'))) ++j;
    if (j >= u.size() || u[j] != 'H' || j == start) continue;
    std::string_view digits(u.data() + start, j - start);
    while (digits.size() > 1 && digits.front() == '0') digits.remove_prefix(1);
    if (digits.size() > 8) continue;
    uint64_t v = 0;
    std::from_chars(digits.data(), digits.data() + digits.size(), v, 16);
    if (v >= 0x80000000u) return u.substr(i, j + 1 - i);
  }
  return std::nullopt;
}

}  // namespace

std::optional<std::string> normalise_instruction(std::string_view instruction, std::string& error) {
  const std::string s(trim_blanks(instruction));
  const std::string u = upper(s);
  if (u.size() >= 3 && is_axis(u[0]) && u[1] == 'C' && is_digit(u[2])) {
    const auto n = small_decimal(std::string_view(u).substr(2));
    if (!n) return s;  // not XCn; leave it to the controller
    if (*n >= 1 && *n <= 16) return s;
    if (*n >= 17 && *n <= 19) return fmt::format("{}C\\{}", u[0], "LPU"[*n - 17]);
    error = fmt::format("'{}': profile must be 1..16, 17 (linear), 18 (parabolic) or 19 (user)", s);
    return std::nullopt;
  }
  if (u.size() == 3 && is_axis(u[0]) &&
      std::string_view("HPVLMB").find(u[1]) != std::string_view::npos &&
      (u[2] == '0' || u[2] == '1'))
    return fmt::format("{}{}{}", u[0], u[1], u[2] == '1' ? '+' : '-');
  if (u.size() >= 3 && is_axis(u[0]) && u[1] == 'R' && is_digit(u[2])) {
    const auto n = small_decimal(std::string_view(u).substr(2));
    if (!n || (*n != 1 && *n != 2 && *n != 10 && *n != 125)) {
      error = fmt::format("'{}': step resolution must be 1, 2, 10 or 125", s);
      return std::nullopt;
    }
    return s;
  }
  if (const auto negative = negative_absolute_position(u)) {
    error = fmt::format(
        "'{}': a negative absolute position; the CN0170's position register "
        "takes only positive numbers (manual p.35) and the axis would run the "
        "other way (p.21)",
        *negative);
    return std::nullopt;
  }
  return signed_relative_distances(s);
}

std::vector<AbsoluteTarget> absolute_targets(std::string_view instruction) {
  std::string s;
  for (char c : upper(instruction))
    if (c != ' ') s += c;
  std::vector<AbsoluteTarget> out;
  for (std::size_t i = 0; i + 2 < s.size(); ++i) {
    const bool term_start = i == 0 || s[i - 1] == '&' || s[i - 1] == ',' || s[i - 1] == '^';
    if (!term_start || (s[i] != 'X' && s[i] != 'Y') || s[i + 1] != '=') continue;
    std::size_t end = i + 2;
    while (end < s.size() && s[end] != '&' && s[end] != ',' && s[end] != '^') ++end;
    const std::string_view n(s.data() + i + 2, end - (i + 2));
    AbsoluteTarget t;
    t.axis = s[i];
    if (n.size() >= 2 && n.back() == 'H') {
      uint64_t v = 0;
      const auto digits = n.substr(0, n.size() - 1);
      const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v, 16);
      if (ec != std::errc() || ptr != digits.data() + digits.size() || v > 0xffffffffu) continue;
      t.raw = static_cast<int32_t>(static_cast<uint32_t>(v));
    } else {
      double v = 0;
      const auto [ptr, ec] = std::from_chars(n.data(), n.data() + n.size(), v);
      if (ec != std::errc() || ptr != n.data() + n.size()) continue;
      t.raw = std::llround(v * 1024);
    }
    out.push_back(t);
  }
  return out;
}

std::optional<std::string> normalise_request(std::string_view request, std::string& error) {
  std::string out;
  for (const auto& part : split_instructions(request)) {
    auto n = normalise_instruction(part, error);
    if (!n) return std::nullopt;
    if (!out.empty()) out += ';';
    out += *n;
  }
  return out;
}

}  // namespace fieldgate::cn0170
