#include "drivers/protocol_file/field_pattern.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cstdlib>
#include <iterator>
#include <limits>
#include <set>
#include <utility>

#include "drivers/printable_bytes.hpp"

namespace fieldgate::protocol_file {

namespace {

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

bool is_hex_digit(char c) {
  return is_digit(c) || (c >= 'A' && c <= 'F') || (c >= 'a' && c <= 'f');
}

// The characters a char or text field carries: printable ASCII.
bool is_printable(int64_t c) {
  return c >= 0x20 && c <= 0x7e;
}

bool is_name_start(char c) {
  return (c >= 'a' && c <= 'z') || c == '_';
}

bool is_name_char(char c) {
  return is_name_start(c) || is_digit(c);
}

bool variable_width(const Field& f) {
  return f.width == 0 && f.type != FieldType::character && f.type != FieldType::bits;
}

// Whether a field of this type always starts with a character `f` (variable width) would take
// as its own.
bool starts_inside(const Field& f, const Piece& next) {
  if (next.field) {
    const auto t = next.field->type;
    return t != FieldType::text && t != FieldType::character;
  }
  const char c = next.literal.front();
  switch (f.type) {
    case FieldType::integer:
      return is_digit(c);
    case FieldType::decimal:
      return is_digit(c) || c == '.';
    case FieldType::hex:
      return is_hex_digit(c);
    default:
      return false;
  }
}

// "int", "int(4)", "decimal(3)", ...: the type and its number, or an error.
bool parse_type(std::string_view spec, Field& field, std::string& error) {
  std::string_view base = spec;
  std::optional<int> number;
  if (const auto open = spec.find('('); open != std::string_view::npos) {
    if (!spec.ends_with(')')) {
      error = fmt::format("'{}': a type's number is written in parentheses, e.g. int(4)", spec);
      return false;
    }
    base = spec.substr(0, open);
    const auto digits = spec.substr(open + 1, spec.size() - open - 2);
    int n = 0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
    if (ec != std::errc() || end != digits.data() + digits.size()) {
      error = fmt::format("'{}': '{}' is not a number", spec, digits);
      return false;
    }
    number = n;
  }
  const auto range = [&](int lo, int hi, std::string_view what) {
    if (*number < lo || *number > hi) {
      error = fmt::format("'{}': {} must be {}..{}", spec, what, lo, hi);
      return false;
    }
    return true;
  };
  if (base == "int") {
    field.type = FieldType::integer;
    if (number && !range(1, 18, "the width")) return false;
    field.width = number.value_or(0);
  } else if (base == "decimal") {
    field.type = FieldType::decimal;
    if (!number) {
      error = fmt::format(
          "'{}': decimal needs its scale, the decimals one count stands for: decimal(4) reads "
          "12.3456 as 123456",
          spec);
      return false;
    }
    if (!range(0, 9, "the scale")) return false;
    field.scale = *number;
  } else if (base == "hex") {
    field.type = FieldType::hex;
    if (number && !range(1, 16, "the width")) return false;
    field.width = number.value_or(0);
  } else if (base == "char") {
    field.type = FieldType::character;
    if (number) {
      error = fmt::format("'{}': char is one character and takes no number", spec);
      return false;
    }
    field.width = 1;
  } else if (base == "bits") {
    field.type = FieldType::bits;
    if (!number) {
      error = fmt::format("'{}': bits needs its count, e.g. bits(32)", spec);
      return false;
    }
    if (!range(1, 63, "the count")) return false;
    field.width = *number;
  } else if (base == "text") {
    field.type = FieldType::text;
    if (number) {
      error = fmt::format("'{}': text takes no number", spec);
      return false;
    }
  } else {
    error = fmt::format(
        "unknown field type '{}' (known: int, int(N), decimal(S), hex, hex(N), char, bits(N), "
        "text)",
        base);
    return false;
  }
  return true;
}

bool multiply_checked(int64_t a, int64_t b, int64_t& out) {
  return !__builtin_mul_overflow(a, b, &out);
}

int64_t power10(int n) {
  int64_t p = 1;
  for (int i = 0; i < n; ++i) p *= 10;
  return p;
}

// [sign] digits, as a whole string.
std::optional<int64_t> integer_value(std::string_view s) {
  bool negative = false;
  if (!s.empty() && (s[0] == '+' || s[0] == '-')) {
    negative = s[0] == '-';
    s.remove_prefix(1);
  }
  if (s.empty()) return std::nullopt;
  uint64_t v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  if (v > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) return std::nullopt;
  return negative ? -static_cast<int64_t>(v) : static_cast<int64_t>(v);
}

// [sign] digits [. digits] with at least one digit, scaled by 10^scale and rounded half away
// from zero where the text has more decimals than the scale.
std::optional<int64_t> decimal_value(std::string_view s, int scale) {
  bool negative = false;
  if (!s.empty() && (s[0] == '+' || s[0] == '-')) {
    negative = s[0] == '-';
    s.remove_prefix(1);
  }
  const auto point = s.find('.');
  const std::string_view whole = s.substr(0, point);
  const std::string_view part = point == std::string_view::npos ? "" : s.substr(point + 1);
  if (whole.empty() && part.empty()) return std::nullopt;
  for (const char c : whole)
    if (!is_digit(c)) return std::nullopt;
  for (const char c : part)
    if (!is_digit(c)) return std::nullopt;
  int64_t v = 0;
  const auto add_digit = [&](char c) {
    return multiply_checked(v, 10, v) && !__builtin_add_overflow(v, c - '0', &v);
  };
  for (const char c : whole)
    if (!add_digit(c)) return std::nullopt;
  const int kept = std::min<int>(scale, static_cast<int>(part.size()));
  for (int i = 0; i < kept; ++i)
    if (!add_digit(part[i])) return std::nullopt;
  for (int i = kept; i < scale; ++i)
    if (!multiply_checked(v, 10, v)) return std::nullopt;
  if (static_cast<int>(part.size()) > scale && part[scale] >= '5')
    if (__builtin_add_overflow(v, 1, &v)) return std::nullopt;
  return negative ? -v : v;
}

// How many characters a variable-width field takes from the start of `s` (0: none fit).
std::size_t take_variable(const Field& f, std::string_view s) {
  std::size_t i = 0;
  if ((f.type == FieldType::integer || f.type == FieldType::decimal) && i < s.size() &&
      (s[i] == '+' || s[i] == '-'))
    ++i;
  const std::size_t start = i;
  bool point = false;
  while (i < s.size()) {
    const char c = s[i];
    if (f.type == FieldType::hex ? is_hex_digit(c) : is_digit(c)) {
      ++i;
    } else if (f.type == FieldType::decimal && c == '.' && !point) {
      point = true;
      ++i;
    } else {
      break;
    }
  }
  return i == start ? 0 : i;
}

std::optional<int64_t> value_of(const Field& f, std::string_view text) {
  switch (f.type) {
    case FieldType::integer:
      return integer_value(text);
    case FieldType::decimal:
      return decimal_value(text, f.scale);
    case FieldType::hex: {
      if (text.empty()) return std::nullopt;
      uint64_t v = 0;
      for (const char c : text) {
        if (!is_hex_digit(c)) return std::nullopt;
        v = v * 16 + static_cast<uint64_t>(is_digit(c) ? c - '0' : (c | 0x20) - 'a' + 10);
      }
      return static_cast<int64_t>(v);
    }
    case FieldType::character:
      return static_cast<unsigned char>(text.front());
    case FieldType::bits: {
      int64_t v = 0;
      int bit = 0;
      for (const char c : text) {
        if (c == '_') continue;
        if (c == '1') v |= int64_t{1} << bit;
        ++bit;
      }
      return v;
    }
    case FieldType::text:
      return 0;
  }
  return std::nullopt;
}

}  // namespace

std::string_view to_string(FieldType type) {
  // In the order of FieldType.
  static constexpr std::string_view kNames[] = {"int", "decimal", "hex", "char", "bits", "text"};
  const auto i = static_cast<std::size_t>(type);
  return i < std::size(kNames) ? kNames[i] : "?";
}

std::optional<FieldPattern> FieldPattern::compile(std::string_view text, PatternError& error) {
  FieldPattern p;
  p.source_ = std::string(text);
  std::set<std::string, std::less<>> names;
  std::string literal;
  const auto flush = [&] {
    if (!literal.empty()) p.pieces_.push_back(Piece{std::exchange(literal, {}), std::nullopt});
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '}') {
      if (i + 1 < text.size() && text[i + 1] == '}') {
        literal += '}';
        ++i;
        continue;
      }
      error = {"a '}' without its '{' (write '}}' for the character)", i};
      return std::nullopt;
    }
    if (c != '{') {
      literal += c;
      continue;
    }
    if (i + 1 < text.size() && text[i + 1] == '{') {
      literal += '{';
      ++i;
      continue;
    }
    const auto close = text.find('}', i);
    if (close == std::string_view::npos) {
      error = {"a '{' without its '}' (write '{{' for the character)", i};
      return std::nullopt;
    }
    const auto inside = text.substr(i + 1, close - i - 1);
    const auto colon = inside.find(':');
    const auto name = inside.substr(0, colon);
    Field f;
    f.offset = i;
    if (name.empty() || !is_name_start(name[0])) {
      error = {fmt::format("'{{{}}}': a field is {{name}} or {{name:type}}, the name in lower "
                           "case",
                           inside),
               i};
      return std::nullopt;
    }
    for (const char n : name)
      if (!is_name_char(n)) {
        error = {fmt::format("'{{{}}}': a field name is lower case letters, digits and _", inside),
                 i};
        return std::nullopt;
      }
    f.name = std::string(name);
    if (colon != std::string_view::npos) {
      std::string why;
      if (!parse_type(inside.substr(colon + 1), f, why)) {
        error = {fmt::format("'{{{}}}': {}", inside, why), i};
        return std::nullopt;
      }
    }
    if (f.name == "addr" && f.type != FieldType::integer) {
      error = {"{addr} is the node's number: int or int(N)", i};
      return std::nullopt;
    }
    // {addr} may stand in each command of a line, and in each part of its reply.
    if (f.name != "_" && f.name != "addr" && !names.insert(f.name).second) {
      error = {fmt::format("field '{}' appears twice", f.name), i};
      return std::nullopt;
    }
    flush();
    p.pieces_.push_back(Piece{{}, f});
    i = close;
  }
  flush();
  for (std::size_t k = 0; k + 1 < p.pieces_.size(); ++k) {
    const auto& piece = p.pieces_[k];
    if (!piece.field) continue;
    const Field& f = *piece.field;
    const Piece& next = p.pieces_[k + 1];
    if (f.type == FieldType::text && next.field) {
      error = {fmt::format("{{{}:text}} is followed by another field: text runs to the next "
                           "literal, so the field after it could never match",
                           f.name),
               f.offset};
      return std::nullopt;
    }
    if (variable_width(f) && f.type != FieldType::text && starts_inside(f, next)) {
      error = {fmt::format("{{{}:{}}} takes every character of its kind, so what follows it "
                           "('{}') could never match: give the field a width",
                           f.name, to_string(f.type),
                           next.field ? "{" + next.field->name + "}" : next.literal),
               f.offset};
      return std::nullopt;
    }
  }
  return p;
}

bool FieldPattern::declare_number(std::size_t piece, const NumberFormat& format, int width,
                                  PatternError& error) {
  if (piece >= pieces_.size() || !pieces_[piece].field) {
    error = {"no field there to declare a number format of", 0};
    return false;
  }
  Field& f = *pieces_[piece].field;
  if ((f.type != FieldType::integer && f.type != FieldType::decimal) || f.name == "addr") {
    error = {fmt::format("{{{}:{}}}: a number format is for the int and decimal(S) fields of a "
                         "reply",
                         f.name, to_string(f.type)),
             f.offset};
    return false;
  }
  const bool variable = width == 0 && f.width == 0;
  const char next = piece + 1 < pieces_.size() && !pieces_[piece + 1].field
                        ? pieces_[piece + 1].literal.front()
                        : '\0';
  const bool taken =
      variable && ((next == '.' && format.form != NumberFormat::Form::integer) ||
                   ((next == 'E' || next == 'e') && format.form == NumberFormat::Form::exponent));
  if (taken) {
    const std::string type = f.type == FieldType::decimal ? fmt::format("decimal({})", f.scale)
                                                          : std::string(to_string(f.type));
    error = {fmt::format("{{{}:{}}} in {} form would take the '{}' that follows it as its own, so "
                         "the pattern could never match: give the field a width",
                         f.name, type, to_string(format.form), next),
             f.offset};
    return false;
  }
  if (width > 0) f.width = width;
  f.number = format;
  return true;
}

std::vector<const Field*> FieldPattern::named_fields() const {
  std::vector<const Field*> out;
  for (const auto& piece : pieces_)
    if (piece.field && piece.field->name != "_" && piece.field->name != "addr")
      out.push_back(&*piece.field);
  return out;
}

bool FieldPattern::has_address() const {
  for (const auto& piece : pieces_)
    if (piece.field && piece.field->name == "addr") return true;
  return false;
}

std::optional<std::vector<Capture>> FieldPattern::match(std::string_view text,
                                                        std::string_view address,
                                                        std::string& why) const {
  std::vector<Capture> captures;
  std::size_t pos = 0;
  for (std::size_t k = 0; k < pieces_.size(); ++k) {
    const Piece& piece = pieces_[k];
    const std::string_view rest = text.substr(pos);
    if (!piece.field) {
      if (!rest.starts_with(piece.literal)) {
        why = fmt::format("expected '{}' at character {}, found '{}'",
                          printable_bytes(piece.literal), pos + 1, printable_bytes(rest));
        return std::nullopt;
      }
      pos += piece.literal.size();
      continue;
    }
    const Field& f = *piece.field;
    if (f.name == "addr") {
      if (!rest.starts_with(address)) {
        why = fmt::format("expected the address '{}' at character {}, found '{}'", address, pos + 1,
                          printable_bytes(rest));
        return std::nullopt;
      }
      pos += address.size();
      continue;
    }
    std::size_t length = 0;
    if (f.type == FieldType::text) {
      if (k + 1 < pieces_.size()) {
        const auto at = rest.find(pieces_[k + 1].literal);
        if (at == std::string_view::npos) {
          why = fmt::format("no '{}' after {{{}:text}}", printable_bytes(pieces_[k + 1].literal),
                            f.name);
          return std::nullopt;
        }
        length = at;
      } else {
        length = rest.size();
      }
    } else if (f.type == FieldType::bits) {
      int bits = 0;
      while (length < rest.size() && bits < f.width) {
        const char c = rest[length];
        if (c == '0' || c == '1') {
          ++bits;
        } else if (c != '_' || bits == 0) {
          break;
        }
        ++length;
      }
      if (bits < f.width) {
        why = fmt::format("{{{}:bits({})}} at character {}: '{}' has {} bit(s)", f.name, f.width,
                          pos + 1, printable_bytes(rest.substr(0, length)), bits);
        return std::nullopt;
      }
    } else if (f.width > 0) {
      length = f.width;
      if (rest.size() < length) {
        why = fmt::format("{{{}:{}({})}} at character {}: only '{}'", f.name, to_string(f.type),
                          f.width, pos + 1, printable_bytes(rest));
        return std::nullopt;
      }
    } else {
      length = f.number ? take_number(*f.number, rest) : take_variable(f, rest);
    }
    const std::string_view taken = rest.substr(0, length);
    if (f.number) {
      std::string reason = "beyond a 64-bit count";
      const auto plain = read_number(*f.number, f.width, taken, reason);
      const auto value =
          plain ? decimal_value(*plain, f.type == FieldType::decimal ? f.scale : 0) : std::nullopt;
      if (!value) {
        why = fmt::format(
            "{{{}:{}}} at character {}: '{}' is no number printed as declared ({}): "
            "{}",
            f.name, to_string(f.type), pos + 1, printable_bytes(taken.empty() ? rest : taken),
            describe(*f.number, f.width), reason);
        return std::nullopt;
      }
      if (f.name != "_") captures.push_back(Capture{f.name, std::string(taken), *value, f.type});
      pos += length;
      continue;
    }
    const auto value = length == 0 && f.type != FieldType::text ? std::nullopt : value_of(f, taken);
    if (!value) {
      why = fmt::format("{{{}:{}}} at character {}: '{}' is not one", f.name, to_string(f.type),
                        pos + 1, printable_bytes(taken.empty() ? rest : taken));
      return std::nullopt;
    }
    if (f.type == FieldType::text)
      for (const char c : taken)
        if (!is_printable(static_cast<unsigned char>(c))) {
          why = fmt::format("{{{}:text}} at character {}: '{}' is not printable text", f.name,
                            pos + 1, printable_bytes(taken));
          return std::nullopt;
        }
    if (f.type == FieldType::character && !is_printable(static_cast<unsigned char>(taken[0]))) {
      why = fmt::format("{{{}:char}} at character {}: not a printable character", f.name, pos + 1);
      return std::nullopt;
    }
    if (f.name != "_") captures.push_back(Capture{f.name, std::string(taken), *value, f.type});
    pos += length;
  }
  if (pos != text.size()) {
    why = fmt::format("'{}' left over after the pattern '{}'", printable_bytes(text.substr(pos)),
                      printable_bytes(source_));
    return std::nullopt;
  }
  return captures;
}

std::optional<std::string> format_field(const Field& f, int64_t value, std::string& why) {
  std::string s;
  switch (f.type) {
    case FieldType::integer:
      s = std::to_string(value);
      if (f.width > 0 && static_cast<int>(s.size()) < f.width) {
        const bool negative = value < 0;
        s.insert(negative ? 1 : 0, std::string(f.width - s.size(), '0'));
      }
      break;
    case FieldType::decimal: {
      const int64_t p = power10(f.scale);
      const uint64_t magnitude =
          value < 0 ? static_cast<uint64_t>(-(value + 1)) + 1 : static_cast<uint64_t>(value);
      s = (value < 0 ? "-" : "") + std::to_string(magnitude / p);
      if (f.scale > 0) s += fmt::format(".{:0{}}", magnitude % p, f.scale);
      break;
    }
    case FieldType::hex:
      if (value < 0) {
        why = fmt::format("{{{}:hex}}: {} is negative", f.name, value);
        return std::nullopt;
      }
      s = f.width > 0 ? fmt::format("{:0{}X}", value, f.width) : fmt::format("{:X}", value);
      break;
    case FieldType::character:
      if (!is_printable(value)) {
        why = fmt::format("{{{}:char}}: {} is not the code of a printable character (32..126)",
                          f.name, value);
        return std::nullopt;
      }
      s = std::string(1, static_cast<char>(value));
      break;
    case FieldType::bits:
      if (value < 0 || (f.width < 63 && value >> f.width)) {
        why = fmt::format("{{{}:bits({})}}: {} does not fit", f.name, f.width, value);
        return std::nullopt;
      }
      for (int b = 0; b < f.width; ++b) s += (value >> b) & 1 ? '1' : '0';
      break;
    case FieldType::text:
      why =
          fmt::format("{{{}:text}} is for replies: a request cannot send a number as text", f.name);
      return std::nullopt;
  }
  if (f.width > 0 && static_cast<int>(s.size()) > f.width) {
    why = fmt::format("{{{}:{}({})}}: {} needs {} characters", f.name, to_string(f.type), f.width,
                      value, s.size());
    return std::nullopt;
  }
  return s;
}

std::optional<std::string> FieldPattern::render(const std::vector<int64_t>& values,
                                                std::string_view address, std::string& why) const {
  std::string out;
  std::size_t next = 0;
  for (const auto& piece : pieces_) {
    if (!piece.field) {
      out += piece.literal;
      continue;
    }
    const Field& f = *piece.field;
    if (f.name == "addr") {
      out += address;
      continue;
    }
    if (f.name == "_") {
      why = "a request cannot send a skipped field {_}";
      return std::nullopt;
    }
    if (next >= values.size()) {
      why = fmt::format("no value for {{{}}}", f.name);
      return std::nullopt;
    }
    const auto s = format_field(f, values[next++], why);
    if (!s) return std::nullopt;
    out += *s;
  }
  return out;
}

}  // namespace fieldgate::protocol_file
