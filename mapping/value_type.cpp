#include "mapping/value_type.hpp"

#include <array>
#include <limits>

namespace fieldgate {

namespace {
// Per type, in enum order: its name in configs, its range and its register count.
struct TypeFacts {
  std::string_view name;
  int64_t min;
  int64_t max;
  int registers;
};
constexpr std::array<TypeFacts, 5> kTypes = {{
    {"bool", 0, 1, 1},
    {"int16", std::numeric_limits<int16_t>::min(), std::numeric_limits<int16_t>::max(), 1},
    {"uint16", 0, std::numeric_limits<uint16_t>::max(), 1},
    {"int32", std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::max(), 2},
    {"uint32", 0, std::numeric_limits<uint32_t>::max(), 2},
}};

const TypeFacts& facts(ValueType type) {
  return kTypes.at(static_cast<std::size_t>(type));
}
}  // namespace

std::optional<ValueType> parse_value_type(std::string_view text) {
  if (text == "boolean") return ValueType::boolean;
  for (std::size_t i = 0; i < kTypes.size(); ++i)
    if (kTypes[i].name == text) return static_cast<ValueType>(i);
  return std::nullopt;
}

std::string_view to_string(ValueType type) {
  return facts(type).name;
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
  return facts(type).registers;
}
int64_t min_value(ValueType type) {
  return facts(type).min;
}
int64_t max_value(ValueType type) {
  return facts(type).max;
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
