#include "drivers/whedco_cmc/whedco_codec.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>

#include "drivers/ascii_blanks.hpp"

namespace fieldgate::whedco {

namespace {

bool is_axis(char c) {
  return c == 'W' || c == 'X' || c == 'Y' || c == 'Z';
}

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

// As the manual prints hex (variables V0-VF, FCa codes 0-A): upper case only. A lower-case
// letter is a garbled character, not a digit.
bool is_hex_digit(char c) {
  return is_digit(c) || (c >= 'A' && c <= 'F');
}

bool is_upper_or_digit(char c) {
  return is_digit(c) || (c >= 'A' && c <= 'Z');
}

char upper(char c) {
  return (c >= 'a' && c <= 'z') ? static_cast<char>(c - 'a' + 'A') : c;
}

std::string lower_words(std::string_view s) {
  std::string out;
  for (const char c : s) out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

enum class EchoMatch { none, partial, full };

// Compares the start of `buffer` with the line, with or without its address character.
EchoMatch match_echo(std::string_view buffer, std::string_view line, std::size_t& length) {
  bool partial = false;
  for (const std::string_view candidate : {line, line.substr(line.empty() ? 0 : 1)}) {
    if (candidate.empty()) continue;
    std::size_t i = 0;
    while (i < candidate.size() && i < buffer.size() && upper(buffer[i]) == upper(candidate[i]))
      ++i;
    if (i == candidate.size()) {
      length = i;
      return EchoMatch::full;
    }
    if (i == buffer.size()) partial = true;
  }
  return partial ? EchoMatch::partial : EchoMatch::none;
}

std::size_t skip_blanks(std::string_view s, std::size_t i) {
  while (i < s.size() && is_ascii_blank(s[i])) ++i;
  return i;
}

int decimals_of(Quantity q) {
  switch (q) {
    case Quantity::length:
      return 4;
    case Quantity::velocity:
      return 2;
    default:
      return 0;
  }
}

__int128 power_of_ten(int n) {
  __int128 p = 1;
  while (n-- > 0) p *= 10;
  return p;
}

// numerator / denominator rounded half away from zero; denominator > 0.
__int128 divide_rounded(__int128 numerator, __int128 denominator) {
  const bool negative = numerator < 0;
  const __int128 magnitude = negative ? -numerator : numerator;
  const __int128 q = (magnitude + denominator / 2) / denominator;
  return negative ? -q : q;
}

struct ScaledMnemonic {
  std::string_view mnemonic;
  Quantity quantity;
  char axis;        // 0: the axis letter follows the mnemonic
  bool reply_only;  // RP/RC/FE: no argument, the reply is a length
};

// Longer mnemonics first where one is a prefix of another's form.
constexpr std::array<ScaledMnemonic, 19> kScaled{{
    {"STP", Quantity::length, 0, false},
    {"SHP", Quantity::length, 0, false},
    {"SIP", Quantity::length, 0, false},
    {"SBP", Quantity::length, 0, false},
    {"AM", Quantity::length, 0, false},
    {"IM", Quantity::length, 0, false},
    {"NO", Quantity::length, 0, false},
    {"PO", Quantity::length, 0, false},
    {"AC", Quantity::acceleration, 0, false},
    {"FS", Quantity::velocity, 0, false},
    // The pair velocity is entered in the units of the pair's first axis (README).
    {"VX", Quantity::velocity, 'X', false},
    {"VW", Quantity::velocity, 'W', false},
    {"RX", Quantity::length, 'X', false},
    {"RW", Quantity::length, 'W', false},
    {"IX", Quantity::length, 'X', false},
    {"IW", Quantity::length, 'W', false},
    {"RP", Quantity::length, 0, true},
    {"RC", Quantity::length, 0, true},
    {"FE", Quantity::length, 0, true},
}};

// Commands a gateway must not send (digest §8.4): they erase memory, copy it between units,
// start diagnostics, or define/edit/teach profiles (every later line would be stored, not run).
constexpr std::array<std::string_view, 8> kForbidden{
    {"CB", "MS", "ML", "DG", "DE", "ED", "X", "TC"}};

bool expand_axis_masks(std::string_view command, std::string& out, std::string& error) {
  out.clear();
  std::size_t i = 0;
  while (i < command.size()) {
    const char c = command[i];
    if (c == ']') {
      error = fmt::format("'{}': ']' without '['", command);
      return false;
    }
    if (c != '[') {
      out += c;
      ++i;
      continue;
    }
    const auto close = command.find(']', i);
    if (close == std::string_view::npos) {
      error = fmt::format("'{}': '[' without ']'", command);
      return false;
    }
    const std::string_view digits = command.substr(i + 1, close - i - 1);
    int64_t mask = -1;
    const auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), mask);
    if (digits.empty() || ec != std::errc{} || p != digits.data() + digits.size()) {
      error = fmt::format("'{}': an axis mask [n] holds a number, found '[{}]'", command, digits);
      return false;
    }
    const auto letters = axis_letters(mask);
    if (!letters) {
      error = fmt::format("axis mask {} selects no axis (1..15: bit 0 X, 1 Y, 2 W, 3 Z)", mask);
      return false;
    }
    const bool axis_set = out == "RA" || out == "RI";
    if (!axis_set && letters->size() != 1) {
      error = fmt::format("axis mask {} selects {} axes ({}); '{}' takes exactly one", mask,
                          letters->size(), *letters, out);
      return false;
    }
    out += *letters;
    i = close + 1;
  }
  return true;
}

}  // namespace

std::optional<Address> parse_address(std::string_view text, std::string& error) {
  Address a;
  const auto slash = text.find('/');
  const std::string_view unit = text.substr(0, slash);
  if (unit.size() != 1 || unit[0] < '0' || unit[0] > '7') {
    error = fmt::format(
        "Whedco CMC-0 address must be one digit 0..7 (DIP switches SW2-1..3), found '{}'", unit);
    return std::nullopt;
  }
  a.unit = unit[0] - '0';
  if (slash != std::string_view::npos) {
    const std::string_view mode = text.substr(slash + 1);
    if (mode == "echo")
      a.mode = EchoMode::echo;
    else if (mode == "non-echo")
      a.mode = EchoMode::non_echo;
    else if (mode == "auto")
      a.mode = EchoMode::automatic;
    else {
      error = fmt::format("Whedco communication format must be auto, echo or non-echo, found '{}'",
                          mode);
      return std::nullopt;
    }
  }
  return a;
}

std::string sent_line(int unit, std::string_view command) {
  std::string out;
  out += static_cast<char>('0' + unit);
  out += command;
  return out;
}

std::string encode_command(int unit, std::string_view command) {
  return sent_line(unit, command) + kTerminator;
}

std::size_t frame_length(std::string_view buffer, std::string_view line, EchoMode mode) {
  std::size_t i = skip_blanks(buffer, 0);
  if (mode != EchoMode::non_echo) {
    std::size_t length = 0;
    switch (match_echo(buffer.substr(i), line, length)) {
      case EchoMatch::partial:
        return 0;
      case EchoMatch::full:
        i += length;
        break;
      case EchoMatch::none:
        break;
    }
  }
  const auto prompt = buffer.find(kPrompt, i);
  return prompt == std::string_view::npos ? 0 : prompt + 1;
}

std::string_view strip_echo(std::string_view frame, std::string_view line, bool& echoed) {
  std::size_t i = skip_blanks(frame, 0);
  std::size_t length = 0;
  echoed = match_echo(frame.substr(i), line, length) == EchoMatch::full;
  if (echoed) i += length;
  return frame.substr(skip_blanks(frame, i));
}

std::optional<std::string> axis_letters(int64_t mask) {
  if (mask < 1 || mask > 15) return std::nullopt;
  std::string letters;
  constexpr std::string_view kOrder = "XYWZ";
  for (std::size_t bit = 0; bit < kOrder.size(); ++bit)
    if (mask & (int64_t{1} << bit)) letters += kOrder[bit];
  return letters;
}

std::optional<PreparedCommand> prepare_command(std::string_view command, std::string& error) {
  if (command.empty()) {
    error = "empty command";
    return std::nullopt;
  }
  for (const char c : command) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '!') {
      error = fmt::format("'{}': '!' makes the unit ignore the whole line (§5.17)", command);
      return std::nullopt;
    }
    if (u < 0x20 || u >= 0x7f) {
      error =
          fmt::format("'{}': control characters are not allowed; the family adds the CR", command);
      return std::nullopt;
    }
    if (c == ' ') {
      error = fmt::format("'{}': Whedco commands contain no spaces", command);
      return std::nullopt;
    }
    if (c >= 'a' && c <= 'z') {
      error = fmt::format("'{}': Whedco commands are upper case", command);
      return std::nullopt;
    }
  }
  if (is_digit(command.front())) {
    error = fmt::format("'{}': the family adds the unit address; start with the mnemonic", command);
    return std::nullopt;
  }
  PreparedCommand p;
  if (!expand_axis_masks(command, p.text, error)) return std::nullopt;
  const std::string& t = p.text;
  for (const auto f : kForbidden) {
    if (t.starts_with(f)) {
      error = fmt::format(
          "'{}': {} is kept out of the gateway (cold boot, memory transfer, diagnostics and "
          "profile definition or editing are commissioning work for a terminal)",
          t, f);
      return std::nullopt;
    }
  }
  if (t == "FC")
    p.kind = QueryKind::unit_fault;
  else if (t.size() == 3 && t.starts_with("FC") && is_axis(t[2]))
    p.kind = QueryKind::axis_fault;
  else if (t == "RDI" || t == "RDB")
    p.kind = QueryKind::bit_list;
  else if (t == "RS" || (t.size() == 3 && t.starts_with("RS") && is_axis(t[2])))
    p.kind = QueryKind::status_word;

  if (t.size() >= 3 && t.starts_with("UR") && is_axis(t[2])) {
    const std::string_view arg = std::string_view(t).substr(3);
    if (arg == "?") {
      p.unit_ratio_axis = t[2];
    } else {
      int64_t v = 0;
      const auto [end, ec] = std::from_chars(arg.data(), arg.data() + arg.size(), v);
      if (!arg.empty() && ec == std::errc{} && end == arg.data() + arg.size() &&
          v >= kMinUnitRatio && v <= kMaxUnitRatio) {
        p.unit_ratio_axis = t[2];
        p.unit_ratio_written = v;
      }
    }
  }

  for (const auto& s : kScaled) {
    if (!t.starts_with(s.mnemonic)) continue;
    std::size_t i = s.mnemonic.size();
    char axis = s.axis;
    if (axis == 0) {
      if (i >= t.size() || !is_axis(t[i])) continue;
      axis = t[i++];
    }
    const std::string_view arg = std::string_view(t).substr(i);
    if (s.reply_only) {
      if (!arg.empty()) continue;
      p.quantity = s.quantity;
      p.axis = axis;
      p.scaled_reply = true;
      break;
    }
    if (arg == "?") {
      p.quantity = s.quantity;
      p.axis = axis;
      p.scaled_reply = true;
      break;
    }
    std::size_t j = 0;
    if (j < arg.size() && (arg[j] == '+' || arg[j] == '-')) ++j;
    const std::size_t digits_begin = j;
    while (j < arg.size() && is_digit(arg[j])) ++j;
    if (j < arg.size() && arg[j] == '.') {
      error = fmt::format(
          "'{}': numbers the unit ratio scales are written in internal units (whole pulses, "
          "pulses/s, pulses/s²); the family converts them to user units",
          t);
      return std::nullopt;
    }
    if (j > digits_begin && j == arg.size()) {
      p.quantity = s.quantity;
      p.axis = axis;
      p.literal_begin = i;
      p.literal_end = t.size();
    }
    break;  // a variable (AMXV3) or anything else goes as written
  }
  return p;
}

std::string user_units(int64_t internal, int unit_ratio, Quantity quantity) {
  const int decimals = decimals_of(quantity);
  const __int128 scaled = divide_rounded(static_cast<__int128>(internal) * power_of_ten(decimals),
                                         unit_ratio > 0 ? unit_ratio : 1);
  const bool negative = scaled < 0;
  const __int128 magnitude = negative ? -scaled : scaled;
  const auto whole = static_cast<uint64_t>(magnitude / power_of_ten(decimals));
  auto fraction = static_cast<uint64_t>(magnitude % power_of_ten(decimals));
  std::string out = negative ? "-" : "";
  out += std::to_string(whole);
  if (fraction != 0) {
    std::string digits = fmt::format("{:0{}}", fraction, decimals);
    while (!digits.empty() && digits.back() == '0') digits.pop_back();
    out += '.' + digits;
  }
  return out;
}

std::string wire_command(const PreparedCommand& command, int unit_ratio) {
  if (command.literal_end == 0) return command.text;
  const std::string_view literal =
      std::string_view(command.text)
          .substr(command.literal_begin, command.literal_end - command.literal_begin);
  int64_t value = 0;
  std::string_view digits = literal;
  if (!digits.empty() && digits.front() == '+') digits.remove_prefix(1);
  const auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (ec != std::errc{} || p != digits.data() + digits.size()) return command.text;
  return command.text.substr(0, command.literal_begin) +
         user_units(value, unit_ratio, command.quantity) + command.text.substr(command.literal_end);
}

std::optional<std::vector<Decimal>> parse_numbers(std::string_view body, bool hex) {
  std::vector<Decimal> out;
  body = trim_blanks(body);
  // One label in front, as in "V1=25000" or "X: 12".
  {
    std::size_t i = 0;
    if (i < body.size() && body[i] >= 'A' && body[i] <= 'Z') {
      while (i < body.size() && is_upper_or_digit(body[i])) ++i;
      if (i < body.size() && (body[i] == '=' || body[i] == ':'))
        body = trim_blanks(body.substr(i + 1));
    }
  }
  std::size_t i = 0;
  while (true) {
    i = skip_blanks(body, i);
    if (i >= body.size()) break;
    std::size_t end = i;
    while (end < body.size() && !is_ascii_blank(body[end])) ++end;
    std::string_view token = body.substr(i, end - i);
    i = end;
    Decimal d;
    bool negative = false;
    if (!hex && (token.front() == '+' || token.front() == '-')) {
      negative = token.front() == '-';
      token.remove_prefix(1);
    }
    if (token.empty()) return std::nullopt;
    __int128 mantissa = 0;
    int digits = 0;
    bool point = false;
    for (const char c : token) {
      int digit = -1;
      if (!hex && c == '.' && !point) {
        point = true;
        continue;
      }
      if (is_digit(c))
        digit = c - '0';
      else if (hex && is_hex_digit(c))
        digit = c - 'A' + 10;
      if (digit < 0) return std::nullopt;
      mantissa = mantissa * (hex ? 16 : 10) + digit;
      if (++digits > 18) return std::nullopt;
      if (point) ++d.decimals;
    }
    if (digits == 0) return std::nullopt;
    d.mantissa = static_cast<int64_t>(negative ? -mantissa : mantissa);
    out.push_back(d);
  }
  return out;
}

std::optional<int64_t> to_internal(const Decimal& value, int64_t factor) {
  const __int128 product = static_cast<__int128>(value.mantissa) * factor;
  const __int128 result = divide_rounded(product, power_of_ten(value.decimals));
  if (result > INT64_MAX || result < INT64_MIN) return std::nullopt;
  return static_cast<int64_t>(result);
}

std::optional<int> axis_fault_from_text(std::string_view text) {
  const std::string t = lower_words(text);
  const auto has = [&](std::string_view word) { return t.find(word) != std::string::npos; };
  if (has("functional")) return 8;
  if (has("power")) return 0;
  if (has("temperature")) return 2;
  if (has("following")) return 3;
  if (has("encoder")) return 4;
  if (has("deadband")) return 5;
  if (has("enable")) return 6;
  if (has("overflow") || has("register")) return 7;
  if (has("current")) return 9;
  if (has("stall")) return 10;
  return std::nullopt;
}

std::string_view axis_fault_text(int code) {
  switch (code) {
    case 0:
      return "Power Failure";
    case 2:
      return "Over-temperature";
    case 3:
      return "Excessive Following Error";
    case 4:
      return "Encoder Lost";
    case 5:
      return "Deadband Exceeded";
    case 6:
      return "Lost Enable";
    case 7:
      return "Position Register Overflow";
    case 8:
      return "Unit Functional";
    case 9:
      return "Over-current";
    case 10:
      return "Motor Stalled";
    default:
      return "unknown fault code";
  }
}

int unit_fault_axis_bit(char axis, bool faulted) {
  int index = 0;
  switch (axis) {
    case 'X':
      index = 0;
      break;
    case 'Y':
      index = 1;
      break;
    case 'W':
      index = 2;
      break;
    default:
      index = 3;
      break;
  }
  return 1 << (index + (faulted ? 4 : 0));
}

std::optional<int64_t> unit_fault_from_text(std::string_view text) {
  int64_t base = kUnitFunctional;
  int64_t axes = 0;
  bool any = false;
  std::size_t i = 0;
  while (i < text.size()) {
    std::size_t end = i;
    while (end < text.size() && text[end] != '\r' && text[end] != '\n') ++end;
    const std::string_view line = trim_blanks(text.substr(i, end - i));
    i = end + 1;
    if (line.empty()) continue;
    any = true;
    const std::string t = lower_words(line);
    const auto has = [&](std::string_view word) { return t.find(word) != std::string::npos; };
    const char axis = upper(line.front());
    if (is_axis(axis) && (line.size() == 1 || line[1] == ' ') && has("faulted")) {
      axes |= unit_fault_axis_bit(axis, true) | unit_fault_axis_bit(axis, false);
    } else if (is_axis(axis) && (line.size() == 1 || line[1] == ' ') && has("responding")) {
      axes |= unit_fault_axis_bit(axis, false);
    } else if (has("functional")) {
      // no fault
    } else if (has("power")) {
      base = kUnitPowerFailure;
    } else if (has("initiali")) {
      base = kUnitAxisInitialized;
    } else if (has("arithmetic") || has("overflow")) {
      base = kUnitArithmeticOverflow;
    } else {
      return std::nullopt;
    }
  }
  if (!any) return std::nullopt;
  return base + axes;
}

std::optional<int64_t> parse_bit_string(std::string_view body) {
  body = trim_blanks(body);
  if (body.size() < 8 || body.size() > 63) return std::nullopt;
  int64_t bits = 0;
  for (std::size_t i = 0; i < body.size(); ++i) {
    if (body[i] == '1')
      bits |= int64_t{1} << i;
    else if (body[i] != '0')
      return std::nullopt;
  }
  return bits;
}

std::string_view to_string(StatusLayout layout) {
  return layout == StatusLayout::outputs
             ? "outputs (bit 0 set point A, 1 set point B, 2 busy, 3 fault)"
             : "busy_first (bit 0 busy, 1 fault)";
}

int64_t to_model_layout(int64_t word, StatusLayout layout) {
  if (layout == StatusLayout::busy_first) return word;
  const int64_t busy = (word >> 2) & 1, fault = (word >> 3) & 1;
  const int64_t set_a = word & 1, set_b = (word >> 1) & 1;
  return (word & ~int64_t{0x30f}) | busy | (fault << 1) | (set_a << 8) | (set_b << 9);
}

std::string_view to_string(StatusForm form) {
  switch (form) {
    case StatusForm::decimal:
      return "decimal";
    case StatusForm::hex:
      return "hex";
    case StatusForm::binary:
      return "binary";
  }
  return "?";
}

std::optional<StatusWord> parse_status_word(std::string_view body, std::optional<StatusForm> known,
                                            std::string& problem) {
  body = trim_blanks(body);
  const auto all = [&](auto pred) {
    return !body.empty() && std::all_of(body.begin(), body.end(), pred);
  };
  StatusWord w;
  if ((body.size() == 8 || body.size() == 16) && all([](char c) { return c == '0' || c == '1'; })) {
    for (const char c : body) w.value = (w.value << 1) | (c == '1' ? 1 : 0);
    w.evidence = StatusForm::binary;
    return w;
  }
  if (!all(is_hex_digit)) {
    problem = fmt::format("'{}' is no status word (decimal, hex or 8/16 binary digits)", body);
    return std::nullopt;
  }
  const bool letters = !all([](char c) { return c >= '0' && c <= '9'; });
  const bool padded = body.size() == 4 && body.front() == '0';
  const bool hex = letters || padded || known == StatusForm::hex;
  if (letters || padded) w.evidence = StatusForm::hex;
  if (body.size() > (hex ? 4u : 5u)) {
    problem = fmt::format("status word '{}' does not fit 16 bits", body);
    return std::nullopt;
  }
  uint32_t v = 0;
  std::from_chars(body.data(), body.data() + body.size(), v, hex ? 16 : 10);
  if (v > 0xffff) {
    problem = fmt::format("status word '{}' does not fit 16 bits", body);
    return std::nullopt;
  }
  w.value = v;
  return w;
}

}  // namespace fieldgate::whedco
