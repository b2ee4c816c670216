#include "drivers/ims_party_line/ims_codec.hpp"

#include <fmt/format.h>

#include <cctype>
#include <charconv>
#include <cmath>

namespace fieldgate::ims {

bool valid_name(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= 0x5b && c <= 0x60);
}

std::optional<char> parse_name(std::string_view text, std::string& error) {
  if (text.size() != 1) {
    error = fmt::format(
        "an IMS unit name is one character (A-Z, a-z, or one of [ \\ ] ^ _ `), found '{}'",
        printable(text));
    return std::nullopt;
  }
  const char c = text.front();
  if (!valid_name(c)) {
    error = fmt::format(
        "'{}' cannot be an IMS unit name: names are A-Z, a-z or one of [ \\ ] ^ _ ` "
        "(^C, CR, LF, @ and * are reserved)",
        printable(text));
    return std::nullopt;
  }
  return c;
}

namespace {

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

// [+-]?digits(.d|.dd)? at the front of text; returns the characters used, 0 if none.
std::size_t scan_number(std::string_view text, double& value) {
  std::size_t i = 0;
  bool negative = false;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) {
    negative = text[i] == '-';
    ++i;
  }
  const std::size_t digits_start = i;
  int64_t whole = 0;
  while (i < text.size() && is_digit(text[i])) {
    if (whole > 100'000'000'000LL) return 0;
    whole = whole * 10 + (text[i] - '0');
    ++i;
  }
  if (i == digits_start) return 0;
  int64_t hundredths = 0;
  if (i < text.size() && text[i] == '.') {
    ++i;
    const std::size_t fraction_start = i;
    while (i < text.size() && is_digit(text[i]) && i - fraction_start < 2) {
      hundredths = hundredths * 10 + (text[i] - '0');
      ++i;
    }
    if (i == fraction_start) return 0;
    if (i - fraction_start == 1) hundredths *= 10;
    if (i < text.size() && is_digit(text[i])) return 0;
  }
  const double magnitude = static_cast<double>(whole) + static_cast<double>(hundredths) / 100.0;
  value = negative ? -magnitude : magnitude;
  return i;
}

std::optional<double> first_field(std::string_view command) {
  if (command.empty()) return std::nullopt;
  const auto data = parse_data(command.substr(1));
  if (!data || data->fields.empty()) return std::nullopt;
  return data->fields.front();
}

}  // namespace

std::optional<CommandData> parse_data(std::string_view text) {
  CommandData data;
  std::size_t i = 0;
  while (i < text.size()) {
    const std::size_t spaces_start = i;
    while (i < text.size() && text[i] == ' ') ++i;
    if (i == text.size()) break;
    // A second field needs a space before it; the first may follow the command directly.
    if (!data.fields.empty() && i == spaces_start) return std::nullopt;
    if (data.fields.size() == 2) return std::nullopt;
    double value = 0;
    const std::size_t used = scan_number(text.substr(i), value);
    if (used == 0) return std::nullopt;
    data.fields.push_back(value);
    i += used;
  }
  return data;
}

CommandClass classify(std::string_view command) {
  if (command.empty()) return CommandClass::unknown;
  switch (command.front()) {
    case 'Z':
    case 'z':
    case '^':
    case ']':
    case '[':
      return CommandClass::query;
    case 'A': {
      const auto v = first_field(command);
      return v && *v == 129 ? CommandClass::query : CommandClass::parameter;
    }
    case 'B':
    case 'D':
    case 'E':
    case 'H':
    case 'I':
    case 'K':
    case 'T':
    case 'V':
    case 'Y':
    case 'l':
    case 'd':
    case 'e':
    case 'h':
    case 'r':
    case 's':
    case 't':
    case 'v':
    case 'k':
      return CommandClass::parameter;
    case 'C': {
      // C0 (or C alone, "0 is used by default") reloads the saved parameters without a write.
      const auto v = first_field(command);
      return !v || *v == 0 ? CommandClass::parameter : CommandClass::eeprom;
    }
    case '+':
    case '-':
    case 'R':
    case 'F':
    case 'G':
    case 'f':
      return CommandClass::index;
    case 'M':
      return CommandClass::velocity;
    case 'O':
    case 'o':
      return CommandClass::origin;
    case 'S':
    case '\\':
      return CommandClass::eeprom;
    case 'P':
    case 'Q':
    case 'q':
    case 'X':
      return CommandClass::no_echo;
    case 'W':
      return CommandClass::wait;
    case kSoftStop:
      return CommandClass::soft_stop;
    case kEscape:
      return CommandClass::hard_stop;
    case kControlC:
      return CommandClass::reset;
    case 'J':
    case 'j':
    case 'L':
    case 'y':
      return CommandClass::program;
    default:
      return CommandClass::unknown;
  }
}

std::string normalize_command(std::string_view command) {
  if (command.size() >= 2 && (command[0] == '+' || command[0] == '-') &&
      (command[1] == '+' || command[1] == '-')) {
    const bool negative = (command[0] == '-') != (command[1] == '-');
    return std::string(1, negative ? '-' : '+') + std::string(command.substr(2));
  }
  return std::string(command);
}

bool single_mode_echo(char name, std::string_view command, std::string_view partial) {
  const std::string line = encode_line(name, command);
  const std::string_view sent = std::string_view(line).substr(0, line.size() - 1);
  return partial == sent || (partial.size() == 1 && partial.front() == name);
}

std::string encode_line(char name, std::string_view command) {
  std::string out;
  out.reserve(command.size() + 2);
  out += name;
  out += normalize_command(command);
  out += kLineFeed;
  return out;
}

bool is_global_character_command(std::string_view command) {
  if (command.size() == 1 && (command[0] == kEscape || command[0] == kControlC)) return true;
  return !command.empty() && command[0] == kSoftStop &&
         (command.size() == 1 || command == "@0" || command == "@1");
}

std::string encode_global(std::string_view command) {
  if (command.size() == 1 && (command[0] == kEscape || command[0] == kControlC))
    return std::string(command);
  if (!command.empty() && command[0] == kSoftStop) return std::string(command) + kLineFeed;
  return std::string(1, kGlobalAddress) + normalize_command(command) + kLineFeed;
}

std::size_t line_length(std::string_view buf) {
  const auto lf = buf.find(kLineFeed);
  return lf == std::string_view::npos ? 0 : lf + 1;
}

bool is_blank_line(std::string_view line) {
  return line.find_first_not_of("\r\n") == std::string_view::npos;
}

EchoMatch match_echo(char name, std::string_view command, std::string_view echo) {
  while (!echo.empty() && echo.front() == '\r') echo.remove_prefix(1);
  const std::string sent = encode_line(name, command);
  if (echo == sent) return EchoMatch::with_name;
  if (echo == std::string_view(sent).substr(1)) return EchoMatch::without_name;
  return EchoMatch::mismatch;
}

std::optional<ResultLine> parse_result(std::string_view line) {
  if (line.empty() || line.back() != kLineFeed) return std::nullopt;
  line.remove_suffix(1);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  ResultLine result;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && line[i] == ' ') ++i;
    if (i == line.size()) break;
    double value = 0;
    const std::size_t used = scan_number(line.substr(i), value);
    if (used == 0) return std::nullopt;
    i += used;
    if (i < line.size() && line[i] != ' ') return std::nullopt;
    const auto hundredths = static_cast<int64_t>(std::llround(value * 100.0));
    result.hundredths.push_back(hundredths);
    result.values.push_back(static_cast<int64_t>(std::llround(value)));
  }
  if (result.values.empty()) return std::nullopt;
  return result;
}

EchoLine parse_echo_line(char name, std::string_view command, std::string_view line) {
  EchoLine out;
  if (line.empty() || line.back() != kLineFeed) return out;
  while (!line.empty() && line.front() == '\r') line.remove_prefix(1);
  std::string_view body = line.substr(0, line.size() - 1);
  if (!body.empty() && body.back() == '\r') {
    out.carriage_return = true;
    body.remove_suffix(1);
  }
  const std::string sent = std::string(1, name) + normalize_command(command);
  // With the name first: the name is never a digit, sign or space, so a line that matches both
  // forms can be read as a value in one of them at most.
  for (const auto form : {EchoMatch::with_name, EchoMatch::without_name}) {
    const std::string_view echo =
        form == EchoMatch::with_name ? std::string_view(sent) : std::string_view(sent).substr(1);
    if (!body.starts_with(echo)) continue;
    const std::string_view rest = body.substr(echo.size());
    // One CR at most ends a line (manual p.11): a second is no part of a reply.
    if (rest.find('\r') != std::string_view::npos) continue;
    if (rest.find_first_not_of(' ') == std::string_view::npos) {
      out.match = form;
      out.rest = std::string(rest);
      return out;
    }
    auto value = parse_result(std::string(rest) + kLineFeed);
    if (!value) continue;
    out.match = form;
    out.rest = std::string(rest);
    out.result = std::move(value);
    return out;
  }
  return out;
}

StrayLine classify_stray(std::string_view line) {
  if (is_blank_line(line)) return StrayLine::blank;
  if (parse_result(line)) return StrayLine::result;
  std::string_view body = line;
  while (!body.empty() && (body.front() == '\r')) body.remove_prefix(1);
  while (!body.empty() && (body.back() == '\n' || body.back() == '\r' || body.back() == ' '))
    body.remove_suffix(1);
  // [name]<query>: the command alone, with or without a name character in front.
  for (std::size_t skip = 0; skip <= 1 && skip < body.size(); ++skip) {
    const std::string_view command = body.substr(skip);
    if (skip == 1 && !valid_name(body.front())) break;
    if (command.empty() || classify(command) != CommandClass::query) continue;
    if (parse_data(command.substr(1))) return StrayLine::query_echo;
  }
  return StrayLine::other;
}

std::string printable(std::string_view bytes) {
  std::string out;
  for (const char c : bytes) {
    switch (c) {
      case '\r':
        out += "\\r";
        break;
      case '\n':
        out += "\\n";
        break;
      case kEscape:
        out += "<ESC>";
        break;
      case kControlC:
        out += "^C";
        break;
      default:
        if (c >= 0x20 && c < 0x7f)
          out += c;
        else
          out += fmt::format("\\x{:02x}", static_cast<unsigned char>(c));
    }
  }
  return out;
}

}  // namespace fieldgate::ims
