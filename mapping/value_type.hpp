#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace fieldgate {

// Types a point or setpoint can have on the Modbus side. Values travel as int64 inside the
// gateway; the type fixes the register count, the range and the sign.
enum class ValueType { boolean, int16, uint16, int32, uint32 };

enum class WordOrder { high_first, low_first };

std::optional<ValueType> parse_value_type(std::string_view text);
std::string_view to_string(ValueType type);
std::string_view to_string(WordOrder order);
std::optional<WordOrder> parse_word_order(std::string_view text);

int register_count(ValueType type);
int64_t min_value(ValueType type);
int64_t max_value(ValueType type);
bool in_range(ValueType type, int64_t value);

// Encodes a value into register_count(type) registers.
std::vector<uint16_t> to_registers(ValueType type, int64_t value, WordOrder order);
// Decodes exactly register_count(type) registers; the value is sign-extended as the type says.
int64_t from_registers(ValueType type, std::span<const uint16_t> words, WordOrder order);

}  // namespace fieldgate
