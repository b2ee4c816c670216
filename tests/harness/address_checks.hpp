#pragma once

// A family's address parser as the family tests check it: a text that parses, to its canonical
// form and number.

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <string_view>

#include "drivers/protocol_family.hpp"

namespace fieldgate::test {

// Parses `text` with the family; checks that it parsed to `canonical` and `number`. The address,
// or nullopt (and a failure) when it did not parse.
inline std::optional<NodeAddress> expect_address(const Family& family, std::string_view text,
                                                 std::string_view canonical, int number) {
  std::string error;
  auto a = family.parse_address(text, error);
  EXPECT_TRUE(a) << text << ": " << error;
  if (!a) return a;
  EXPECT_EQ(a->text, canonical) << text;
  EXPECT_EQ(a->number, number) << text;
  return a;
}

}  // namespace fieldgate::test
