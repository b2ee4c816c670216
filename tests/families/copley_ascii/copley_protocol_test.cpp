#include "sim/copley/protocol.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "sim/copley/variables.hpp"

namespace fieldgate::sim::copley {
namespace {

std::optional<Error> address_error(std::string_view line) {
  return parse_address(line).error;
}

std::optional<Error> command_error(std::string_view body) {
  return parse_command(body).error;
}

// Each text must be refused with its error; a failing row names the text.
struct ErrorCase {
  const char* text;
  Error error;
};

template <class Check>
void expect_errors(Check check, const std::vector<ErrorCase>& cases) {
  for (const ErrorCase& c : cases) {
    SCOPED_TRACE(c.text);
    EXPECT_EQ(check(c.text), c.error);
  }
}

TEST(CopleyAddress, Prefixes) {
  auto p = parse_address("g r0x32");
  EXPECT_FALSE(p.error);
  EXPECT_FALSE(p.address.node);
  EXPECT_EQ(p.body, "g r0x32");

  p = parse_address("8 i r0");
  EXPECT_EQ(p.address.node, 8);
  EXPECT_FALSE(p.address.axis);
  EXPECT_EQ(p.body, "i r0");

  p = parse_address(".b g r0x32");
  EXPECT_FALSE(p.address.node);
  EXPECT_EQ(p.address.axis, 'b');
  EXPECT_EQ(p.body, "g r0x32");

  p = parse_address("2.c g r0x32");
  EXPECT_EQ(p.address.node, 2);
  EXPECT_EQ(p.address.axis, 'c');
  EXPECT_EQ(p.body, "g r0x32");

  EXPECT_EQ(parse_address("127 r").address.node, 127);
}

TEST(CopleyAddress, Errors) {
  const std::vector<ErrorCase> refused = {
      {"128 g r0x32", Error::bad_node},   {"99999999999 g r0x32", Error::bad_node},
      {"3g r0x32", Error::parse_error},   {"3", Error::parse_error},
      {".d g r0x32", Error::parse_error}, {".B g r0x32", Error::parse_error},
      {"2.cg r0x32", Error::parse_error}, {".", Error::parse_error},
  };
  expect_errors(address_error, refused);
}

TEST(CopleyCommand, Get) {
  const auto p = parse_command("g r0x30");
  ASSERT_FALSE(p.error);
  EXPECT_EQ(p.command.code, Code::get);
  EXPECT_EQ(p.command.bank, Bank::ram);
  EXPECT_EQ(p.command.variable, 0x30);
  EXPECT_EQ(parse_command("g f48").command.variable, 0x30);  // decimal IDs
  EXPECT_EQ(parse_command("g f48").command.bank, Bank::flash);
  EXPECT_EQ(parse_command("g r0x6B").command.variable, 0x6b);
}

TEST(CopleyCommand, SetValues) {
  const auto p = parse_command("s r0x6B -7936 200 0 775 1550 775 -12774 32763 5813");
  ASSERT_FALSE(p.error);
  EXPECT_EQ(p.command.values,
            (std::vector<std::int64_t>{-7936, 200, 0, 775, 1550, 775, -12774, 32763, 5813}));
  EXPECT_EQ(parse_command("s r0xa9 0xfff60001").command.values[0], 0xfff60001);
  EXPECT_EQ(parse_command("s r0xa9 0xffff60001").command.values[0], 0xffff60001);
}

TEST(CopleyCommand, GrammarErrors) {
  const std::vector<ErrorCase> refused = {
      {"t2", Error::parse_error},
      {"s r 0x30 1000", Error::parse_error},
      {"g 0x32", Error::parse_error},  // no memory bank (App. B)
      {"g x0x32", Error::parse_error},
      {"g R0x32", Error::parse_error},
      {"g r0xzz", Error::parse_error},
      {"g r0x30 ", Error::parse_error},
      {"s r0x30  1200", Error::parse_error},
      {"s r0x30 12x", Error::parse_error},
      {"s r0x30 +5", Error::parse_error},
      {"r 1", Error::parse_error},
      {"i 0", Error::parse_error},
      {"", Error::parse_error},
      {"x", Error::unknown_command},
      {"q r0x30", Error::unknown_command},
  };
  expect_errors(command_error, refused);
}

TEST(CopleyCommand, DataCountErrors) {
  const std::vector<ErrorCase> refused = {
      {"g", Error::not_enough_data},   {"c", Error::not_enough_data},
      {"s", Error::not_enough_data},   {"t", Error::not_enough_data},
      {"i", Error::not_enough_data},   {"g r0x30 5", Error::too_much_data},
      {"t 1 2", Error::too_much_data}, {"i r0 1 2", Error::too_much_data},
  };
  expect_errors(command_error, refused);
}

TEST(CopleyCommand, RangeErrors) {
  const std::vector<ErrorCase> refused = {
      {"t 3", Error::out_of_range},
      {"i r32", Error::out_of_range},
      {"s r0x30 99999999999999999999", Error::out_of_range},
      {"g r99999999999999999999", Error::unknown_variable},
  };
  expect_errors(command_error, refused);
}

TEST(CopleyCommand, TrajectoryAndRegisters) {
  auto p = parse_command("t 1");
  ASSERT_FALSE(p.error);
  EXPECT_EQ(p.command.code, Code::trajectory);
  EXPECT_EQ(p.command.values, std::vector<std::int64_t>{1});
  p = parse_command("i r31 -5");
  ASSERT_FALSE(p.error);
  EXPECT_EQ(p.command.cvm_register, 31);
  EXPECT_EQ(p.command.values, std::vector<std::int64_t>{-5});
  EXPECT_EQ(parse_command("r").command.code, Code::reset);
}

TEST(CopleyReplies, Formats) {
  const std::vector<std::int64_t> one{1200};
  const std::vector<std::int64_t> two{258, 0};
  EXPECT_EQ(ok_reply(), "ok\r");
  EXPECT_EQ(values_reply(one), "v 1200\r");
  EXPECT_EQ(values_reply(one, true), "v1200\r");
  EXPECT_EQ(values_reply(two), "v 258 0\r");
  EXPECT_EQ(register_reply(-35), "r -35\r");
  EXPECT_EQ(error_reply(Error::parse_error), "e 33\r");
}

TEST(CopleyVariables, CatalogMatchesTheDigest) {
  // Every ID of digest §4, 0x70–0x77 expanded.
  const std::vector<int> digest_ids = {
      0x00, 0x01, 0x02, 0x0c, 0x15, 0x17, 0x18, 0x19, 0x1a, 0x1b, 0x1c, 0x1d, 0x1e,
      0x20, 0x21, 0x22, 0x23, 0x24, 0x25, 0x26, 0x27, 0x28, 0x29, 0x2a, 0x2c, 0x2d,
      0x2f, 0x30, 0x32, 0x33, 0x34, 0x35, 0x36, 0x37, 0x39, 0x3a, 0x3b, 0x3c, 0x3d,
      0x5e, 0x5f, 0x6a, 0x6b, 0x70, 0x71, 0x72, 0x73, 0x74, 0x75, 0x76, 0x77, 0x90,
      0xa0, 0xa4, 0xa6, 0xa8, 0xa9, 0xab, 0xae, 0xb0, 0xb8, 0xb9, 0xbf, 0xc2, 0xc3,
      0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xcb, 0xcc, 0xcd, 0xce, 0xcf, 0xe3};
  EXPECT_EQ(variable_catalog().size(), digest_ids.size());
  for (const int id : digest_ids) EXPECT_NE(find_variable(id), nullptr) << std::hex << id;
  const VariableInfo* pp = find_variable(0x30);
  ASSERT_NE(pp, nullptr);
  EXPECT_TRUE(pp->in_ram && pp->in_flash);
  EXPECT_EQ(find_variable(0x6b)->value_count(), 9u);
  EXPECT_EQ(find_variable(0x72)->value_count(), 2u);
  EXPECT_FALSE(find_variable(0x90)->in_flash);
  EXPECT_EQ(find_variable(0x32)->access, Access::monitor);
  EXPECT_EQ(find_variable(0xa0)->access, Access::read_only);
  EXPECT_EQ(find_variable(0x31), nullptr);
}

}  // namespace
}  // namespace fieldgate::sim::copley
