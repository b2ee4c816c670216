#include <gtest/gtest.h>

#include "mapping/value_type.hpp"

namespace fieldgate {
namespace {

TEST(ValueType, Int32HighWordFirst) {
  const auto words = to_registers(ValueType::int32, -2, WordOrder::high_first);
  EXPECT_EQ(words, (std::vector<uint16_t>{0xffff, 0xfffe}));
  EXPECT_EQ(from_registers(ValueType::int32, words, WordOrder::high_first), -2);
}

TEST(ValueType, Int32LowWordFirst) {
  const auto words = to_registers(ValueType::int32, 0x12345678, WordOrder::low_first);
  EXPECT_EQ(words, (std::vector<uint16_t>{0x5678, 0x1234}));
  EXPECT_EQ(from_registers(ValueType::int32, words, WordOrder::low_first), 0x12345678);
}

TEST(ValueType, SixteenBitSignedness) {
  const uint16_t w[] = {0xffff};
  EXPECT_EQ(from_registers(ValueType::int16, w, WordOrder::high_first), -1);
  EXPECT_EQ(from_registers(ValueType::uint16, w, WordOrder::high_first), 65535);
  const uint16_t big[] = {0x8000, 0x0000};
  EXPECT_EQ(from_registers(ValueType::uint32, big, WordOrder::high_first), 0x80000000);
  EXPECT_EQ(from_registers(ValueType::int32, big, WordOrder::high_first), INT32_MIN);
}

TEST(ValueType, Ranges) {
  EXPECT_TRUE(in_range(ValueType::int16, -32768));
  EXPECT_FALSE(in_range(ValueType::int16, 32768));
  EXPECT_FALSE(in_range(ValueType::uint32, -1));
  EXPECT_EQ(register_count(ValueType::uint32), 2);
  EXPECT_EQ(register_count(ValueType::boolean), 1);
  EXPECT_EQ(parse_value_type("int32"), ValueType::int32);
  EXPECT_FALSE(parse_value_type("float"));
}

}  // namespace
}  // namespace fieldgate
