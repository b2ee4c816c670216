#include "mapping/value_type.hpp"

#include <limits>

namespace fieldgate {

std::optional<ValueType> parse_value_type(std::string_view text) {
  if (text == "bool" || text == "boolean") return ValueType::boolean;
  if (text == "int16") return ValueType::int16;
  if (text == "uint16") return ValueType::uint16;
  if (text == "int32") return ValueType::int32;
  if (text == "uint32") return ValueType::uint32;
  return std::nullopt;
}

std::string_view to_string(ValueType type) {
  switch (type) {
    case ValueType::boolean:
      return "bool";
    case ValueType::int16:
      return "int16";
    case ValueType::uint16:
      return "uint16";
    case ValueType::int32:
      return "int32";
    case ValueType::uint32:
      return "uint32";
  }
  return "?";
}

std::string_view to_string(WordOrder order) {
  return order == WordOrder::high_first ? "high_first" : "low_first";
}

std::optional<WordOrder> parse_word_order(std::string_view text) {
  if (text == "high_first" || text == "abcd") return WordOrder::high_first;
  if (text == "low_first" || text == "cdab") return WordOrder::low_first;
  return std::nullopt;
}

int register_count(ValueType type) {
  return (type == ValueType::int32 || type == ValueType::uint32) ? 2 : 1;
}

int64_t min_value(ValueType type) {
  switch (type) {
    case ValueType::boolean:
      return 0;
    case ValueType::int16:
      return std::numeric_limits<int16_t>::min();
    case ValueType::uint16:
      return 0;
    case ValueType::int32:
      return std::numeric_limits<int32_t>::min();
    case ValueType::uint32:
      return 0;
  }
  return 0;
}

int64_t max_value(ValueType type) {
  switch (type) {
    case ValueType::boolean:
      return 1;
    case ValueType::int16:
      return std::numeric_limits<int16_t>::max();
    case ValueType::uint16:
      return std::numeric_limits<uint16_t>::max();
    case ValueType::int32:
      return std::numeric_limits<int32_t>::max();
    case ValueType::uint32:
      return std::numeric_limits<uint32_t>::max();
  }
  return 0;
}

bool in_range(ValueType type, int64_t value) {
  return value >= min_value(type) && value <= max_value(type);
}

std::vector<uint16_t> to_registers(ValueType type, int64_t value, WordOrder order) {
  const auto bits = static_cast<uint32_t>(value);
  if (register_count(type) == 1) return {static_cast<uint16_t>(bits & 0xffffu)};
  const auto high = static_cast<uint16_t>(bits >> 16);
  const auto low = static_cast<uint16_t>(bits & 0xffffu);
  if (order == WordOrder::high_first) return {high, low};
  return {low, high};
}

int64_t from_registers(ValueType type, std::span<const uint16_t> words, WordOrder order) {
  switch (type) {
    case ValueType::boolean:
      return words[0] != 0 ? 1 : 0;
    case ValueType::int16:
      return static_cast<int16_t>(words[0]);
    case ValueType::uint16:
      return words[0];
    case ValueType::int32:
    case ValueType::uint32: {
      const uint32_t high = order == WordOrder::high_first ? words[0] : words[1];
      const uint32_t low = order == WordOrder::high_first ? words[1] : words[0];
      const uint32_t bits = (high << 16) | low;
      if (type == ValueType::int32) return static_cast<int32_t>(bits);
      return bits;
    }
  }
  return 0;
}

}  // namespace fieldgate
