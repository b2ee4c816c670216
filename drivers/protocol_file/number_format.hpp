#pragma once

#include <fmt/format.h>

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include "drivers/printable_bytes.hpp"

namespace fieldgate::protocol_file {

// How a controller prints a number in a reply (docs/protocol-files.md, "Numbers as the controller
// prints them"): its sign, what pads it to a fixed width, and its form. A reply field with a
// declared format takes exactly that and nothing else; a field without one keeps the lenient
// reading of its type (an optional + or -, digits).
struct NumberFormat {
  enum class Sign {
    optional,        // '+', '-' or nothing
    minus,           // '-' before a negative, nothing before the others
    plus_or_minus,   // '+' or '-' before every number
    space_or_minus,  // ' ' or '-' before every number (Galil: " 1000", "-250")
  };
  enum class Pad {
    none,    // no padding: no leading zero but a lone 0 before the point
    zeros,   // to the field's width with zeros, after the sign
    spaces,  // to the field's width with spaces, before the sign
  };
  enum class Form {
    integer,   // digits
    decimal,   // digits, a point, decimals
    exponent,  // one digit, optional point and decimals, E or e, optional sign, 1-3 digits
  };
  Sign sign = Sign::optional;
  Pad pad = Pad::none;
  Form form = Form::integer;
  int places = -1;  // decimals after the point (of the mantissa, in exponent form); -1: any
};

inline std::string_view to_string(NumberFormat::Sign sign) {
  switch (sign) {
    case NumberFormat::Sign::optional:
      return "optional";
    case NumberFormat::Sign::minus:
      return "minus";
    case NumberFormat::Sign::plus_or_minus:
      return "plus_or_minus";
    case NumberFormat::Sign::space_or_minus:
      return "space_or_minus";
  }
  return "?";
}

inline std::string_view to_string(NumberFormat::Pad pad) {
  switch (pad) {
    case NumberFormat::Pad::none:
      return "none";
    case NumberFormat::Pad::zeros:
      return "zeros";
    case NumberFormat::Pad::spaces:
      return "spaces";
  }
  return "?";
}

inline std::string_view to_string(NumberFormat::Form form) {
  switch (form) {
    case NumberFormat::Form::integer:
      return "integer";
    case NumberFormat::Form::decimal:
      return "decimal";
    case NumberFormat::Form::exponent:
      return "exponent";
  }
  return "?";
}

// "sign space_or_minus, 8 characters padded with zeros, decimal with 3 places": for messages.
inline std::string describe(const NumberFormat& f, int width) {
  std::string s = fmt::format("sign {}, ", to_string(f.sign));
  s += width > 0 ? fmt::format("{} characters padded with {}", width, to_string(f.pad))
                 : std::string("no padding");
  s += fmt::format(", {}", to_string(f.form));
  if (f.form != NumberFormat::Form::integer)
    s +=
        f.places < 0 ? std::string(" with any decimals") : fmt::format(" with {} places", f.places);
  return s;
}

namespace number_format_detail {

inline bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

inline std::size_t digits_at(std::string_view s, std::size_t i) {
  std::size_t n = 0;
  while (i + n < s.size() && is_digit(s[i + n])) ++n;
  return n;
}

}  // namespace number_format_detail

// How many characters a number of this format without a fixed width takes from the start of
// `s`: a sign character, digits, a point and decimals, an exponent. What it took is then read by
// read_number(), which refuses what the format does not print.
inline std::size_t take_number(const NumberFormat& f, std::string_view s) {
  using number_format_detail::digits_at;
  std::size_t i = 0;
  if (i < s.size() && (s[i] == '+' || s[i] == '-' || s[i] == ' ')) ++i;
  i += digits_at(s, i);
  if (f.form != NumberFormat::Form::integer && i < s.size() && s[i] == '.') {
    ++i;
    i += digits_at(s, i);
  }
  if (f.form == NumberFormat::Form::exponent && i < s.size() && (s[i] == 'E' || s[i] == 'e')) {
    ++i;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) ++i;
    i += digits_at(s, i);
  }
  return i;
}

// The number `text` (the whole of the field: `width` characters where it has a width) as the
// format prints it, rewritten as [-]digits[.digits] for the value's arithmetic; nullopt, with
// `why`, for anything else.
inline std::optional<std::string> read_number(const NumberFormat& f, int width,
                                              std::string_view text, std::string& why) {
  using number_format_detail::digits_at;
  using Sign = NumberFormat::Sign;
  std::string_view s = text;
  std::size_t spaces = 0;
  if (f.pad == NumberFormat::Pad::spaces)
    while (spaces < s.size() && s[spaces] == ' ') ++spaces;
  s.remove_prefix(spaces);
  char sign = 0;
  if (!s.empty() && (s[0] == '+' || s[0] == '-' || s[0] == ' ')) {
    sign = s[0];
    s.remove_prefix(1);
  }
  bool sign_ok = false;
  switch (f.sign) {
    case Sign::optional:
      sign_ok = sign != ' ';
      break;
    case Sign::minus:
      sign_ok = sign == 0 || sign == '-';
      break;
    case Sign::plus_or_minus:
      sign_ok = sign == '+' || sign == '-';
      break;
    case Sign::space_or_minus:
      // Padded with spaces, the last of them is the sign of a number that is not negative.
      sign_ok = sign == '-' || sign == ' ' || (sign == 0 && spaces > 0);
      break;
  }
  if (!sign_ok) {
    why = sign == 0 ? fmt::format("no sign before '{}'", printable_bytes(s))
                    : fmt::format("'{}' is not its sign", printable_bytes(std::string(1, sign)));
    return std::nullopt;
  }
  const std::size_t whole = digits_at(s, 0);
  if (whole == 0) {
    why = "no digit where its digits start";
    return std::nullopt;
  }
  if (f.form == NumberFormat::Form::exponent && whole != 1) {
    why = "an exponent form has one digit before its point";
    return std::nullopt;
  }
  if (whole > 1 && s[0] == '0' && f.pad != NumberFormat::Pad::zeros) {
    why = "a leading zero, and the number is not padded with zeros";
    return std::nullopt;
  }
  std::size_t i = whole;
  std::string_view decimals;
  const bool point = i < s.size() && s[i] == '.';
  if (point) {
    if (f.form == NumberFormat::Form::integer) {
      why = "a point in an integer";
      return std::nullopt;
    }
    decimals = s.substr(i + 1, digits_at(s, i + 1));
    i += 1 + decimals.size();
  }
  if (f.form != NumberFormat::Form::integer) {
    const bool places_ok = f.places < 0 ? !point || !decimals.empty()
                           : f.places == 0
                               ? !point
                               : point && decimals.size() == static_cast<std::size_t>(f.places);
    if (!places_ok) {
      why = f.places < 0 ? std::string("a point without decimals")
                         : fmt::format("{} decimal(s), not {}", decimals.size(), f.places);
      return std::nullopt;
    }
  }
  int exponent = 0;
  if (f.form == NumberFormat::Form::exponent) {
    if (i >= s.size() || (s[i] != 'E' && s[i] != 'e')) {
      why = "no exponent (E)";
      return std::nullopt;
    }
    ++i;
    bool negative_exponent = false;
    if (i < s.size() && (s[i] == '+' || s[i] == '-')) negative_exponent = s[i++] == '-';
    const std::size_t n = digits_at(s, i);
    if (n == 0 || n > 3) {
      why = "an exponent is 1 to 3 digits";
      return std::nullopt;
    }
    for (std::size_t k = 0; k < n; ++k) exponent = exponent * 10 + (s[i + k] - '0');
    if (negative_exponent) exponent = -exponent;
    i += n;
  }
  if (i != s.size()) {
    why = fmt::format("'{}' after the number", printable_bytes(s.substr(i)));
    return std::nullopt;
  }
  if (width > 0 && static_cast<int>(text.size()) != width) {
    why = fmt::format("{} characters, not {}", text.size(), width);
    return std::nullopt;
  }
  std::string digits = std::string(s.substr(0, whole)) + std::string(decimals);
  // Where the point stands in `digits` once the exponent has moved it.
  const long at = static_cast<long>(whole) + exponent;
  std::string out = sign == '-' ? "-" : "";
  if (at <= 0) {
    out += "0." + std::string(static_cast<std::size_t>(-at), '0') + digits;
  } else if (static_cast<std::size_t>(at) >= digits.size()) {
    out += digits + std::string(static_cast<std::size_t>(at) - digits.size(), '0');
  } else {
    out += digits.substr(0, static_cast<std::size_t>(at)) + "." +
           digits.substr(static_cast<std::size_t>(at));
  }
  return out;
}

}  // namespace fieldgate::protocol_file
