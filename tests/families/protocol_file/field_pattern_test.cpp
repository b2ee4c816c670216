// Field patterns of protocol files: what a reply pattern takes and refuses, how requests are
// written, and the templates refused when compiled because they could never match.
#include <gtest/gtest.h>

#include "drivers/protocol_file/field_pattern.hpp"

namespace fieldgate::protocol_file {
namespace {

FieldPattern compiled(std::string_view text) {
  PatternError e;
  auto p = FieldPattern::compile(text, e);
  EXPECT_TRUE(p) << text << ": " << e.message;
  return p ? *p : FieldPattern{};
}

std::vector<Capture> matched(std::string_view pattern, std::string_view text,
                             std::string_view address = "1") {
  std::string why;
  auto c = compiled(pattern).match(text, address, why);
  EXPECT_TRUE(c) << pattern << " on " << text << ": " << why;
  return c ? *c : std::vector<Capture>{};
}

std::string refusal(std::string_view pattern, std::string_view text,
                    std::string_view address = "1") {
  std::string why;
  const auto c = compiled(pattern).match(text, address, why);
  EXPECT_FALSE(c) << pattern << " took " << text;
  return why;
}

PatternError compile_error(std::string_view text) {
  PatternError e;
  EXPECT_FALSE(FieldPattern::compile(text, e)) << text;
  return e;
}

TEST(FieldPattern, SmcStateReplyGivesTheErrorWordAndTheState) {
  const auto c = matched("{addr}TS{errors:hex(4)}{state:hex(2)}", "1TS000033");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].name, "errors");
  EXPECT_EQ(c[0].value, 0);
  EXPECT_EQ(c[1].value, 0x33);
  EXPECT_EQ(matched("{addr}TS{errors:hex(4)}{state:hex(2)}", "12TS02001e", "12")[0].value, 0x200);
}

TEST(FieldPattern, AnotherNodesAddressIsNoMatch) {
  const auto why = refusal("{addr}TS{errors:hex(4)}{state:hex(2)}", "2TS000033", "1");
  EXPECT_NE(why.find("address '1'"), std::string::npos) << why;
}

TEST(FieldPattern, DecimalsBecomeCountsOfTheScale) {
  EXPECT_EQ(matched("{addr}TP{p:decimal(4)}", "1TP12.3456")[0].value, 123456);
  EXPECT_EQ(matched("{addr}TP{p:decimal(4)}", "1TP-0.5")[0].value, -5000);
  EXPECT_EQ(matched("{addr}TP{p:decimal(4)}", "1TP7")[0].value, 70000);
  EXPECT_EQ(matched("{addr}TP{p:decimal(4)}", "1TP+.25")[0].value, 2500);
  // More decimals than the scale: rounded half away from zero.
  EXPECT_EQ(matched("{addr}TP{p:decimal(4)}", "1TP1.23455")[0].value, 12346);
  EXPECT_EQ(matched("{addr}TP{p:decimal(4)}", "1TP-1.23455")[0].value, -12346);
  EXPECT_EQ(matched("{addr}TP{p:decimal(4)}", "1TP2.000049")[0].value, 20000);
}

TEST(FieldPattern, WhatTheFieldCannotBeIsNoValue) {
  const std::pair<const char*, std::string_view> cases[] = {
      {"{addr}TP{p:decimal(4)}", "1TP"},
      {"{addr}TP{p:decimal(4)}", "1TP1.2.3"},
      {"{addr}TP{p:decimal(4)}", "1TP1e5"},
      {"{addr}TP{p:decimal(4)}", "1TP-"},
      {"{addr}TS{e:hex(4)}{s:hex(2)}", "1TS00003"},    // one digit short
      {"{addr}TS{e:hex(4)}{s:hex(2)}", "1TS0000333"},  // one left over
      {"{addr}TS{e:hex(4)}{s:hex(2)}", "1TS00G033"},
      {"{n:int}", "99999999999999999999"},  // beyond int64
      {"{c:char}", "\x01"},
      // A garbled byte is no character of the reply (an SMC100 error query's '@' hit by noise
      // must not read as error 0xC0).
      {"{addr}TE{c:char}", "1TE\xc0"},
      {"{c:char}", "\x7f"},
      {"{code:int}, {message:text}", "0, NO ERR\xc2R"},
      // Bit strings: one short, a leading separator, a digit that is no bit.
      {"*{addr}TAS{s:bits(8)}", "*1TAS1000_000"},
      {"*{addr}TAS{s:bits(8)}", "*1TAS_1000_0001"},
      {"*{addr}TAS{s:bits(8)}", "*1TAS1000_0002"},
  };
  for (const auto& [pattern, text] : cases) refusal(pattern, text);
}

TEST(FieldPattern, BitStringsReadBitOneFirstAndSkipUnderscores) {
  const auto c = matched("*{addr}TAS{s:bits(8)}", "*1TAS1000_0001");
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].value, 0x81);
}

TEST(FieldPattern, TextRunsToTheNextLiteralAndSkippedFieldsAreDropped) {
  const auto c = matched("{code:int}, {_:int}, {message:text}", "113, 1883, MOTOR NOT ENABLED");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(c[0].value, 113);
  EXPECT_EQ(c[1].text, "MOTOR NOT ENABLED");
  EXPECT_EQ(matched("E{code:text};{n:int}", "Eabc;5")[0].text, "abc");
}

TEST(FieldPattern, FixedWidthIntegersAndAddressesAreZeroPadded) {
  const auto p = compiled("{addr}PA{target:decimal(4)}");
  std::string why;
  EXPECT_EQ(p.render({123456}, "1", why).value_or(why), "1PA12.3456");
  EXPECT_EQ(p.render({-5}, "1", why).value_or(why), "1PA-0.0005");
  EXPECT_EQ(p.render({0}, "1", why).value_or(why), "1PA0.0000");
  const auto q = compiled("X{v:int(3)}Y{h:hex(4)}B{b:bits(4)}");
  EXPECT_EQ(q.render({7, 0xab, 5}, "", why).value_or(why), "X007Y00ABB1010");
  EXPECT_EQ(q.render({-7, 0, 0}, "", why).value_or(why), "X-07Y0000B0000");
  EXPECT_FALSE(q.render({1000, 0, 0}, "", why));
  EXPECT_NE(why.find("needs 4 characters"), std::string::npos) << why;
  EXPECT_FALSE(q.render({1, -1, 0}, "", why));
  EXPECT_FALSE(q.render({1, 0, 16}, "", why));
  EXPECT_FALSE(q.render({1, 0}, "", why));
}

TEST(FieldPattern, BracesAreWrittenTwice) {
  EXPECT_EQ(matched("{{{n:int}}}", "{42}")[0].value, 42);
}

TEST(FieldPattern, TemplatesThatCouldNeverMatchAreRefusedAtTheirField) {
  EXPECT_EQ(compile_error("TP{a:int}{b:int}").offset, 2u);
  EXPECT_EQ(compile_error("TS{e:hex}A").offset, 2u);
  EXPECT_EQ(compile_error("{p:decimal(2)}.5").offset, 0u);
  EXPECT_EQ(compile_error("{t:text}{n:int}").offset, 0u);
  EXPECT_NE(compile_error("{x:float}").message.find("unknown field type 'float'"),
            std::string::npos);
  EXPECT_NE(compile_error("{x:decimal}").message.find("scale"), std::string::npos);
  EXPECT_EQ(compile_error("AB{x:int").offset, 2u);
  EXPECT_EQ(compile_error("AB}").offset, 2u);
  EXPECT_NE(compile_error("{a:int},{a:int}").message.find("twice"), std::string::npos);
  EXPECT_NE(compile_error("{Ab}").message.find("lower case"), std::string::npos);
  EXPECT_NE(compile_error("{addr:hex}").message.find("int"), std::string::npos);
  EXPECT_NE(compile_error("{x:int(40)}").message.find("1..18"), std::string::npos);
  // A fixed width tells the fields apart.
  PatternError e;
  EXPECT_TRUE(FieldPattern::compile("{a:int(2)}{b:int}", e));
  EXPECT_TRUE(FieldPattern::compile("{a:int}{u:char}", e));
}

}  // namespace
}  // namespace fieldgate::protocol_file
