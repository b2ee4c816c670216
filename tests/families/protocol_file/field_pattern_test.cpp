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
  // The address in each command of a line.
  std::string why;
  EXPECT_EQ(compiled("{addr}GO;{addr}TPC").render({}, "2", why).value_or(why), "2GO;2TPC");
  refusal("{addr}GO:{addr}TPC", "2GO:3TPC", "2");
}

// Numbers as controllers print them: a declared format takes exactly what it says, and anything
// else is no value (a garbled reply), never another value.
using Sign = NumberFormat::Sign;
using Pad = NumberFormat::Pad;
using Form = NumberFormat::Form;

NumberFormat format(Sign sign, Pad pad = Pad::none, Form form = Form::integer, int places = -1) {
  NumberFormat f;
  f.sign = sign;
  f.pad = pad;
  f.form = form;
  f.places = places;
  return f;
}

// The pattern with `f` declared on its first field.
FieldPattern declared(std::string_view text, const NumberFormat& f, int width = 0) {
  auto p = compiled(text);
  std::size_t k = 0;
  while (k < p.pieces().size() && !p.pieces()[k].field) ++k;
  PatternError e;
  EXPECT_TRUE(p.declare_number(k, f, width, e)) << text << ": " << e.message;
  return p;
}

// The first capture's value, or why there is none.
std::string read(const FieldPattern& p, std::string_view text) {
  std::string why;
  const auto c = p.match(text, "1", why);
  if (!c) return "no: " + why;
  return c->empty() ? "no capture" : std::to_string(c->front().value);
}

void expect_refused(const FieldPattern& p, std::initializer_list<std::string_view> texts) {
  for (const auto text : texts)
    EXPECT_EQ(read(p, text).substr(0, 3), "no:") << "'" << text << "' read as " << read(p, text);
}

TEST(NumberFormats, SpaceOrMinusIsGalilsSign) {
  const auto p = declared("{p:int}\r\n", format(Sign::space_or_minus));
  EXPECT_EQ(read(p, " 1000\r\n"), "1000");
  EXPECT_EQ(read(p, "-250\r\n"), "-250");
  EXPECT_EQ(read(p, " 0\r\n"), "0");
  expect_refused(p, {"1000\r\n", "+1000\r\n", "  1000\r\n", "- 250\r\n", " -250\r\n", "--250\r\n",
                     " 01000\r\n", " \r\n", " 1.5\r\n"});
  EXPECT_NE(read(p, "1000\r\n")
                .find("'1000' is no number printed as declared (sign "
                      "space_or_minus, no padding, integer): no sign before "
                      "'1000'"),
            std::string::npos)
      << read(p, "1000\r\n");
}

TEST(NumberFormats, MinusOnlyAndPlusOrMinus) {
  const auto minus = declared("P{p:int}", format(Sign::minus));
  EXPECT_EQ(read(minus, "P1000"), "1000");
  EXPECT_EQ(read(minus, "P-250"), "-250");
  EXPECT_EQ(read(minus, "P0"), "0");
  expect_refused(minus, {"P+1000", "P 1000", "P-", "P", "P007"});
  const auto both = declared("P{p:int}", format(Sign::plus_or_minus));
  EXPECT_EQ(read(both, "P+1000"), "1000");
  EXPECT_EQ(read(both, "P-250"), "-250");
  EXPECT_EQ(read(both, "P+0"), "0");
  expect_refused(both, {"P1000", "P 1000", "P+-1", "P+"});
}

TEST(NumberFormats, PaddedWithSpacesToAWidth) {
  const auto p = declared("P{p:int}X", format(Sign::minus, Pad::spaces), 8);
  EXPECT_EQ(read(p, "P    1000X"), "1000");
  EXPECT_EQ(read(p, "P    -250X"), "-250");
  EXPECT_EQ(read(p, "P-1234567X"), "-1234567");
  EXPECT_EQ(read(p, "P12345678X"), "12345678");
  expect_refused(p, {"P   1000X", "P     1000X", "P   01000X", "P  - 250X", "P1000    X",
                     "P   +1000X", "P        X"});
  // With a space for a sign, the last space before the digits is the sign.
  const auto galil = declared("{p:int}", format(Sign::space_or_minus, Pad::spaces), 6);
  EXPECT_EQ(read(galil, "  1000"), "1000");
  EXPECT_EQ(read(galil, "  -250"), "-250");
  expect_refused(galil, {"123456", " -0250"});
}

TEST(NumberFormats, PaddedWithZerosAfterTheSign) {
  const auto p = declared("{p:int}", format(Sign::space_or_minus, Pad::zeros), 8);
  EXPECT_EQ(read(p, " 0001000"), "1000");
  EXPECT_EQ(read(p, "-0000250"), "-250");
  EXPECT_EQ(read(p, " 0000000"), "0");
  expect_refused(p, {"00001000", "0-000250", "    1000", " 001000", " 00001000"});
  // int(N) is a width already: the declaration pads it.
  const auto fixed = declared("{p:int(5)}", format(Sign::plus_or_minus, Pad::zeros));
  EXPECT_EQ(read(fixed, "+0042"), "42");
  expect_refused(fixed, {"00042", " 0042"});
}

TEST(NumberFormats, DecimalsWithTheirPlaces) {
  const auto three =
      declared("{p:decimal(3)}", format(Sign::space_or_minus, Pad::none, Form::decimal, 3));
  EXPECT_EQ(read(three, " 1.500"), "1500");
  EXPECT_EQ(read(three, "-0.250"), "-250");
  expect_refused(three, {" 1.5", " 1", " 1.5000", " 01.500", " .500", "1.500", " 1,500"});
  // Places beyond the scale round half away from zero, as an undeclared decimal(S) does.
  const auto rounded = declared("{p:decimal(2)}", format(Sign::minus, Pad::none, Form::decimal, 3));
  EXPECT_EQ(read(rounded, "1.235"), "124");
  EXPECT_EQ(read(rounded, "-1.235"), "-124");
  // Without places: any decimals, the point optional, but never a bare point.
  const auto any = declared("{p:decimal(4)}", format(Sign::minus, Pad::none, Form::decimal));
  EXPECT_EQ(read(any, "12.3456"), "123456");
  EXPECT_EQ(read(any, "7"), "70000");
  expect_refused(any, {"5.", ".5", "+5", "1.2.3"});
  // A decimal(S) field printed as a whole number.
  const auto whole = declared("{p:decimal(2)}", format(Sign::minus, Pad::none, Form::integer));
  EXPECT_EQ(read(whole, "12"), "1200");
  expect_refused(whole, {"12.0"});
}

TEST(NumberFormats, ExponentForm) {
  const auto p = declared("{p:decimal(3)}", format(Sign::minus, Pad::none, Form::exponent, 4));
  EXPECT_EQ(read(p, "1.2345E+03"), "1234500");
  EXPECT_EQ(read(p, "-2.5000e-01"), "-250");
  EXPECT_EQ(read(p, "1.2345E3"), "1234500");
  EXPECT_EQ(read(p, "0.0000E+00"), "0");
  expect_refused(p, {"12.345E+02", "1.234E+03", "1.2345", "1.2345E+1234", "1.2345E+", "1.2345E",
                     "+1.2345E+03", "1.2345F+03"});
  // Too large for a 64-bit count: no value.
  EXPECT_NE(read(p, "9.9999E+99").find("beyond a 64-bit count"), std::string::npos)
      << read(p, "9.9999E+99");
  // An int field in exponent form is rounded to the count.
  const auto count = declared("{n:int},", format(Sign::minus, Pad::none, Form::exponent));
  EXPECT_EQ(read(count, "1.5E0,"), "2");
  EXPECT_EQ(read(count, "2.5E-1,"), "0");
  EXPECT_EQ(read(count, "-4E2,"), "-400");
}

TEST(NumberFormats, WhatADeclarationCannotBeIsRefusedAtTheField) {
  PatternError e;
  auto hex = compiled("S{s:hex(2)}");
  EXPECT_FALSE(hex.declare_number(1, format(Sign::minus), 0, e));
  EXPECT_EQ(e.offset, 1u);
  EXPECT_NE(e.message.find("int and decimal(S)"), std::string::npos) << e.message;
  auto before_e = compiled("{p:decimal(2)}E");
  EXPECT_FALSE(before_e.declare_number(0, format(Sign::minus, Pad::none, Form::exponent), 0, e));
  EXPECT_NE(e.message.find("would take the 'E'"), std::string::npos) << e.message;
  auto before_point = compiled("{p:int}.");
  EXPECT_FALSE(
      before_point.declare_number(0, format(Sign::minus, Pad::none, Form::exponent), 0, e));
  // A width tells them apart.
  EXPECT_TRUE(before_e.declare_number(0, format(Sign::minus, Pad::none, Form::exponent), 9, e))
      << e.message;
  EXPECT_EQ(read(before_e, "1.50E+002E"), "15000");
}

TEST(NumberFormats, WithoutADeclarationAFieldReadsAsBefore) {
  EXPECT_EQ(read(compiled("{p:int}"), "+007"), "7");
  EXPECT_EQ(read(compiled("{p:decimal(1)}"), "-.25"), "-3");
  expect_refused(compiled("{p:int}"), {" 1000"});
}

}  // namespace
}  // namespace fieldgate::protocol_file
