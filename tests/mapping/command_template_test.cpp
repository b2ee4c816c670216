#include <gtest/gtest.h>

#include "mapping/command_template.hpp"

namespace fieldgate {
namespace {

TEST(CommandTemplate, RendersPlaceholders) {
  std::string error;
  auto t = CommandTemplate::compile("s r0xca {target}", error);
  ASSERT_TRUE(t) << error;
  EXPECT_EQ(t->placeholders(), std::vector<std::string>{"target"});
  EXPECT_EQ(t->render([](std::string_view) { return -40000; }), "s r0xca -40000");
}

TEST(CommandTemplate, HexFormatsAndLiteralBraces) {
  std::string error;
  auto t = CommandTemplate::compile("{{X}}{v:x}/{v:X}", error);
  ASSERT_TRUE(t) << error;
  EXPECT_EQ(t->render([](std::string_view) { return 0xab; }), "{X}ab/AB");
}

TEST(CommandTemplate, RejectsBadPlaceholders) {
  std::string error;
  for (const char* bad : {"s {", "s }", "s {}", "s {a b}", "s {v:q}"}) {
    error.clear();
    EXPECT_FALSE(CommandTemplate::compile(bad, error)) << bad;
    EXPECT_FALSE(error.empty()) << bad;
  }
}

}  // namespace
}  // namespace fieldgate
