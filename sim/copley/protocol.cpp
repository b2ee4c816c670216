#include "sim/copley/protocol.hpp"

#include <charconv>
#include <limits>

namespace fieldgate::sim::copley {
namespace {

constexpr int kMaxNodeId = 127;

bool is_digit(char c) {
  return c >= '0' && c <= '9';
}

enum class NumberStatus { ok, malformed, too_large };

// Decimal or 0x hex, optionally negative (values only). No '+', no spaces.
NumberStatus parse_number(std::string_view text, bool allow_negative, std::int64_t& out) {
  bool negative = false;
  if (allow_negative && !text.empty() && text.front() == '-') {
    negative = true;
    text.remove_prefix(1);
  }
  int base = 10;
  if (text.size() >= 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    base = 16;
    text.remove_prefix(2);
  }
  if (text.empty() || text.front() == '-' || text.front() == '+') return NumberStatus::malformed;
  std::uint64_t magnitude = 0;
  const auto [end, error] =
      std::from_chars(text.data(), text.data() + text.size(), magnitude, base);
  if (end != text.data() + text.size()) return NumberStatus::malformed;
  if (error == std::errc::result_out_of_range) return NumberStatus::too_large;
  if (error != std::errc()) return NumberStatus::malformed;
  if (magnitude > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) {
    return NumberStatus::too_large;
  }
  out = negative ? -static_cast<std::int64_t>(magnitude) : static_cast<std::int64_t>(magnitude);
  return NumberStatus::ok;
}

// Parameters are separated by exactly one space; an empty token means a doubled, leading or
// trailing space, which the amplifier rejects as a parse error.
std::optional<std::vector<std::string_view>> split_parameters(std::string_view text) {
  std::vector<std::string_view> tokens;
  if (text.empty()) return tokens;
  std::size_t begin = 0;
  while (true) {
    const std::size_t space = text.find(' ', begin);
    const std::string_view token = text.substr(begin, space - begin);
    if (token.empty()) return std::nullopt;
    tokens.push_back(token);
    if (space == std::string_view::npos) break;
    begin = space + 1;
  }
  return tokens;
}

std::optional<Error> parse_variable(std::string_view token, Command& command) {
  if (token.empty() || (token.front() != 'r' && token.front() != 'f')) return Error::parse_error;
  command.bank = token.front() == 'r' ? Bank::ram : Bank::flash;
  std::int64_t id = 0;
  switch (parse_number(token.substr(1), false, id)) {
    case NumberStatus::ok:
      break;
    case NumberStatus::malformed:
      return Error::parse_error;
    case NumberStatus::too_large:
      return Error::unknown_variable;
  }
  command.variable = id > std::numeric_limits<int>::max() ? -1 : static_cast<int>(id);
  if (command.variable < 0) return Error::unknown_variable;
  return std::nullopt;
}

std::optional<Error> parse_value(std::string_view token, std::int64_t& value) {
  switch (parse_number(token, true, value)) {
    case NumberStatus::ok:
      return std::nullopt;
    case NumberStatus::malformed:
      return Error::parse_error;
    case NumberStatus::too_large:
      return Error::out_of_range;
  }
  return Error::parse_error;
}

bool known_code(char c) {
  return c == 's' || c == 'g' || c == 'c' || c == 'r' || c == 't' || c == 'i';
}

}  // namespace

AddressParse parse_address(std::string_view line) {
  AddressParse result;
  result.body = line;
  std::size_t i = 0;
  if (!line.empty() && is_digit(line[0])) {
    while (i < line.size() && is_digit(line[i])) ++i;
    const std::string_view digits = line.substr(0, i);
    if (i == line.size() || (line[i] != ' ' && line[i] != '.')) {
      result.error = Error::parse_error;
      return result;
    }
    int node = kMaxNodeId + 1;
    if (digits.size() <= 9) std::from_chars(digits.data(), digits.data() + digits.size(), node);
    result.address.node = node;
  }
  if (i < line.size() && line[i] == '.') {
    // ".b " : period, axis letter, one space.
    if (i + 2 >= line.size() || line[i + 2] != ' ' || line[i + 1] < 'a' || line[i + 1] > 'c') {
      result.error = Error::parse_error;
      return result;
    }
    result.address.axis = line[i + 1];
    i += 3;
  } else if (result.address.node) {
    ++i;  // the single space after the node ID
  }
  result.body = line.substr(i);
  if (result.address.node && *result.address.node > kMaxNodeId) result.error = Error::bad_node;
  return result;
}

CommandParse parse_command(std::string_view body) {
  CommandParse result;
  Command& command = result.command;
  if (body.empty()) {
    result.error = Error::parse_error;
    return result;
  }
  const char code = body.front();
  if (!known_code(code)) {
    result.error = Error::unknown_command;
    return result;
  }
  command.code = static_cast<Code>(code);
  // `t2`, `gr0x30`: the code must be followed by one space (or, for `r`, the end of line).
  if (body.size() > 1 && body[1] != ' ') {
    result.error = Error::parse_error;
    return result;
  }
  const std::string_view rest = body.size() > 1 ? body.substr(2) : std::string_view{};
  if (body.size() > 1 && rest.empty()) {
    result.error = Error::parse_error;  // trailing space
    return result;
  }
  const auto tokens = split_parameters(rest);
  if (!tokens) {
    result.error = Error::parse_error;
    return result;
  }
  const std::size_t count = tokens->size();
  auto fail = [&](Error error) {
    result.error = error;
    return result;
  };

  switch (command.code) {
    case Code::reset:
      if (count != 0) return fail(Error::parse_error);
      return result;
    case Code::get:
    case Code::copy:
      if (count == 0) return fail(Error::not_enough_data);
      if (auto error = parse_variable((*tokens)[0], command)) return fail(*error);
      if (count > 1) return fail(Error::too_much_data);
      return result;
    case Code::set:
      if (count == 0) return fail(Error::not_enough_data);
      if (auto error = parse_variable((*tokens)[0], command)) return fail(*error);
      for (std::size_t k = 1; k < count; ++k) {
        std::int64_t value = 0;
        if (auto error = parse_value((*tokens)[k], value)) return fail(*error);
        command.values.push_back(value);
      }
      return result;
    case Code::trajectory: {
      if (count == 0) return fail(Error::not_enough_data);
      if (count > 1) return fail(Error::too_much_data);
      std::int64_t sub = 0;
      if (auto error = parse_value((*tokens)[0], sub)) return fail(*error);
      if (sub < 0 || sub > 2) return fail(Error::out_of_range);
      command.values.push_back(sub);
      return result;
    }
    case Code::cvm_register: {
      if (count == 0) return fail(Error::not_enough_data);
      if (count > 2) return fail(Error::too_much_data);
      const std::string_view operand = (*tokens)[0];
      std::int64_t index = 0;
      if (operand.size() < 2 || operand.front() != 'r' ||
          parse_number(operand.substr(1), false, index) == NumberStatus::malformed) {
        return fail(Error::parse_error);
      }
      if (parse_number(operand.substr(1), false, index) != NumberStatus::ok || index > 31) {
        return fail(Error::out_of_range);
      }
      command.cvm_register = static_cast<int>(index);
      if (count == 2) {
        std::int64_t value = 0;
        if (auto error = parse_value((*tokens)[1], value)) return fail(*error);
        command.values.push_back(value);
      }
      return result;
    }
  }
  return result;
}

std::string ok_reply() {
  return "ok\r";
}

std::string error_reply(Error error, bool compact) {
  return std::string(compact ? "e" : "e ") + std::to_string(static_cast<int>(error)) + "\r";
}

std::string values_reply(std::span<const std::int64_t> values, bool compact) {
  std::string out = compact ? "v" : "v ";
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (k > 0) out += ' ';
    out += std::to_string(values[k]);
  }
  return out + "\r";
}

std::string register_reply(std::int64_t value, bool compact) {
  return std::string(compact ? "r" : "r ") + std::to_string(value) + "\r";
}

}  // namespace fieldgate::sim::copley
