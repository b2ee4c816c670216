// Codec vectors from shared/protocols/ims-indexer.md: §2 byte-level examples, §4 query formats
// and §11 transcripts.
#include <gtest/gtest.h>

#include "drivers/ims_party_line/ims_codec.hpp"

namespace fieldgate::ims {
namespace {

std::string bytes(std::initializer_list<int> list) {
  std::string s;
  for (int b : list) s += static_cast<char>(b);
  return s;
}

// §2 "Byte-level examples" and §11 #1.
TEST(ImsCodec, AddressedLinesAreNameCommandLineFeed) {
  EXPECT_EQ(encode_line('X', "+1000"), bytes({0x58, 0x2B, 0x31, 0x30, 0x30, 0x30, 0x0A}));
  EXPECT_EQ(encode_line('A', "Z"), bytes({0x41, 0x5A, 0x0A}));
  EXPECT_EQ(encode_line('A', "^"), bytes({0x41, 0x5E, 0x0A}));
  EXPECT_EQ(encode_line('A', "A129"), bytes({0x41, 0x41, 0x31, 0x32, 0x39, 0x0A}));
  EXPECT_EQ(encode_line('B', "R-200.25"),
            bytes({0x42, 0x52, 0x2D, 0x32, 0x30, 0x30, 0x2E, 0x32, 0x35, 0x0A}));
  // Never a CR in party mode (§1, §8.1).
  EXPECT_EQ(encode_line('A', "Z").find('\r'), std::string::npos);
}

TEST(ImsCodec, SignedRelativeDistancesAreRewritten) {
  EXPECT_EQ(normalize_command("+-500"), "-500");
  EXPECT_EQ(normalize_command("-+500"), "-500");
  EXPECT_EQ(normalize_command("--500"), "+500");
  EXPECT_EQ(normalize_command("+500"), "+500");
  EXPECT_EQ(normalize_command("R-500"), "R-500");
  EXPECT_EQ(encode_line('A', "+-200.5"), "A-200.5\n");
}

TEST(ImsCodec, GlobalFormsCarryNoName) {
  EXPECT_EQ(encode_global("\x1b"), bytes({0x1B}));
  EXPECT_EQ(encode_global("\x03"), bytes({0x03}));
  EXPECT_EQ(encode_global("@"), "@\n");
  EXPECT_EQ(encode_global("@1"), "@1\n");
  EXPECT_EQ(encode_global("M0"), "*M0\n");
  EXPECT_EQ(encode_global("+-5"), "*-5\n");
  EXPECT_TRUE(is_global_character_command("\x1b"));
  EXPECT_TRUE(is_global_character_command("\x03"));
  EXPECT_TRUE(is_global_character_command("@0"));
  EXPECT_FALSE(is_global_character_command("@2"));
  EXPECT_FALSE(is_global_character_command("M0"));
  EXPECT_FALSE(is_global_character_command("\x1b\x1b"));
}

// §2 "Valid names" and "Invalid names".
TEST(ImsCodec, Names) {
  for (char c : std::string("AZaz[\\]^_`")) EXPECT_TRUE(valid_name(c)) << c;
  for (char c : std::string("@*\r\n\x03\x1b 019{~")) EXPECT_FALSE(valid_name(c)) << int(c);
  std::string error;
  EXPECT_EQ(parse_name("X", error), 'X');
  EXPECT_FALSE(parse_name("AB", error));
  EXPECT_NE(error.find("one character"), std::string::npos) << error;
  EXPECT_FALSE(parse_name("*", error));
  EXPECT_NE(error.find("reserved"), std::string::npos) << error;
  EXPECT_FALSE(parse_name("", error));
}

// §2 host procedure step 3: the echo may or may not carry the name.
TEST(ImsCodec, EchoWithOrWithoutTheName) {
  EXPECT_EQ(match_echo('X', "+1000", "X+1000\n"), EchoMatch::with_name);
  EXPECT_EQ(match_echo('X', "+1000", "+1000\n"), EchoMatch::without_name);
  EXPECT_EQ(match_echo('A', "Z", "AZ\n"), EchoMatch::with_name);
  EXPECT_EQ(match_echo('A', "Z", "Z\n"), EchoMatch::without_name);
  EXPECT_EQ(match_echo('A', "A129", "AA129\n"), EchoMatch::with_name);
  EXPECT_EQ(match_echo('A', "A129", "A129\n"), EchoMatch::without_name);
  // A late CR of an earlier completion in front is not part of the echo.
  EXPECT_EQ(match_echo('A', "Z", "\rAZ\n"), EchoMatch::with_name);
  EXPECT_EQ(match_echo('A', "Z", "BZ\n"), EchoMatch::mismatch);
  EXPECT_EQ(match_echo('A', "Z", "Z\r\n"), EchoMatch::mismatch);
  EXPECT_EQ(match_echo('A', "Z", "AZ"), EchoMatch::mismatch);
  EXPECT_EQ(match_echo('B', "+-5", "-5\n"), EchoMatch::without_name);
}

// §4: "optional space padding, -?\d+(\.\d\d)?, then CR LF".
TEST(ImsCodec, ResultLines) {
  auto r = parse_result("   1000\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values, std::vector<int64_t>{1000});
  r = parse_result("  9\r\n");  // §11 #14: moving + homing
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values.front() & status::moving, status::moving);
  EXPECT_EQ(r->values.front() & status::homing, status::homing);
  r = parse_result("-200.25\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->hundredths, std::vector<int64_t>{-20025});
  EXPECT_EQ(r->values, std::vector<int64_t>{-200});
  r = parse_result(" 200.5\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->hundredths, std::vector<int64_t>{20050});
  EXPECT_EQ(r->values, std::vector<int64_t>{201});  // rounded half away from zero
  r = parse_result("-8388607\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values, std::vector<int64_t>{-8388607});
  r = parse_result("   1000\n");  // a missing CR is tolerated
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values, std::vector<int64_t>{1000});
}

// §11 #10-12: `[` lines, ten values each.
TEST(ImsCodec, NvmReadLines) {
  auto r = parse_result("32 15 5 0 11 33 22 45 0 0\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values, (std::vector<int64_t>{32, 15, 5, 0, 11, 33, 22, 45, 0, 0}));
  r = parse_result("5 10 255 243 129 26 192 167 253 137\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values.size(), 10u);
  r = parse_result("26 192 36 249 196 49\r\n");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->values.back(), 49);  // the name '1'
}

TEST(ImsCodec, WhatIsNoResultLine) {
  EXPECT_FALSE(parse_result("\"32.\r\n"));  // X in party mode (§2)
  EXPECT_FALSE(parse_result("#\r\n"));      // ESC / end of program mode (Single mode)
  EXPECT_FALSE(parse_result("\r\n"));       // a completion
  EXPECT_FALSE(parse_result("   1000\r"));  // no LF yet
  EXPECT_FALSE(parse_result("1000.123\r\n"));
  EXPECT_FALSE(parse_result("10-00\r\n"));
  EXPECT_FALSE(parse_result("AZ\n"));
}

TEST(ImsCodec, Framing) {
  EXPECT_EQ(line_length("AZ\n   1000\r\n"), 3u);
  EXPECT_EQ(line_length("   1000\r\n"), 9u);
  EXPECT_EQ(line_length("   1000\r"), 0u);
  EXPECT_TRUE(is_blank_line("\r\n"));
  EXPECT_TRUE(is_blank_line("\n"));
  EXPECT_FALSE(is_blank_line(" \r\n"));
}

// §1 line syntax and §11 #2-5.
TEST(ImsCodec, DataFields) {
  for (const char* s : {"+1000", "+ 1000"}) {
    auto d = parse_data(std::string_view(s).substr(1));
    ASSERT_TRUE(d) << s;
    EXPECT_EQ(d->fields, std::vector<double>{1000}) << s;
  }
  for (const char* s : {"H 0", "H0"}) {
    auto d = parse_data(std::string_view(s).substr(1));
    ASSERT_TRUE(d) << s;
    EXPECT_EQ(d->fields, std::vector<double>{0}) << s;
  }
  auto d = parse_data("");  // `H` alone: "0 is used by default"
  ASSERT_TRUE(d);
  EXPECT_TRUE(d->fields.empty());
  d = parse_data(" -1000");
  ASSERT_TRUE(d);
  EXPECT_EQ(d->fields, std::vector<double>{-1000});
  for (const char* s : {" 0 5", "0 5"}) {
    d = parse_data(s);
    ASSERT_TRUE(d) << s;
    EXPECT_EQ(d->fields, (std::vector<double>{0, 5})) << s;
  }
  d = parse_data(" 300.6 56");
  ASSERT_TRUE(d);
  EXPECT_DOUBLE_EQ(d->fields[0], 300.6);
  d = parse_data("-8388607.99");
  ASSERT_TRUE(d);
  EXPECT_FALSE(parse_data("0 5 6"));  // at most two fields
  EXPECT_FALSE(parse_data("20,40"));
  EXPECT_FALSE(parse_data("1.234"));
  EXPECT_FALSE(parse_data("1."));
  EXPECT_FALSE(parse_data("x"));
}

// §11 "Per-command examples, exactly as printed": every one parses and is known.
TEST(ImsCodec, EveryPrintedExampleParsesAndIsClassified) {
  struct Example {
    const char* text;
    CommandClass kind;
  };
  const Example examples[] = {
      {"@ ", CommandClass::soft_stop},
      {"A 129", CommandClass::query},
      {"A 48", CommandClass::parameter},
      {"B 50 250", CommandClass::parameter},
      {"C2 ", CommandClass::eeprom},
      {"D 0", CommandClass::parameter},
      {"E 100", CommandClass::parameter},
      {"F 500 1", CommandClass::index},
      {"G 1001", CommandClass::index},
      {"H 1 ", CommandClass::parameter},
      {"I 400 ", CommandClass::parameter},
      {"J 10 5", CommandClass::program},
      {"K 20 40", CommandClass::parameter},
      {"L 20 1", CommandClass::program},
      {"M+2000", CommandClass::velocity},
      {"O", CommandClass::origin},
      {"P0", CommandClass::no_echo},
      {"Q 100", CommandClass::no_echo},
      {"R-200.25", CommandClass::index},
      {"S", CommandClass::eeprom},
      {"T 233 100", CommandClass::parameter},
      {"V 1000", CommandClass::parameter},
      {"W 100", CommandClass::wait},
      {"X", CommandClass::no_echo},
      {"Y 1 75", CommandClass::parameter},
      {"Z 1", CommandClass::query},
      {"[120", CommandClass::query},
      {"] 0", CommandClass::query},
      {"-200.5", CommandClass::index},
      {"+200.5", CommandClass::index},
      {"^", CommandClass::query},
      {"\\ 100 20", CommandClass::eeprom},
      {"d 10", CommandClass::parameter},
      {"e 500", CommandClass::parameter},
      {"f 1", CommandClass::index},
      {"h 8", CommandClass::parameter},
      {"k 300.6 56", CommandClass::parameter},
      {"l 1 ", CommandClass::parameter},
      {"o ", CommandClass::origin},
      {"q ", CommandClass::no_echo},
      {"r 5 ", CommandClass::parameter},
      {"s 100", CommandClass::parameter},
      {"t 10", CommandClass::parameter},
      {"v 500", CommandClass::parameter},
      {"y", CommandClass::program},
      {"z 1", CommandClass::query},
  };
  for (const auto& e : examples) {
    const std::string_view text(e.text);
    EXPECT_TRUE(parse_data(text.substr(1))) << e.text;
    EXPECT_EQ(classify(text), e.kind) << e.text;
  }
  EXPECT_EQ(classify("C0"), CommandClass::parameter);  // reload, no EEPROM write
  EXPECT_EQ(classify("C"), CommandClass::parameter);
  EXPECT_EQ(classify("C8"), CommandClass::eeprom);
  EXPECT_EQ(classify("\x1b"), CommandClass::hard_stop);
  EXPECT_EQ(classify("\x03"), CommandClass::reset);
  EXPECT_EQ(classify("x"), CommandClass::unknown);
  EXPECT_EQ(classify(""), CommandClass::unknown);
}

TEST(ImsCodec, PrintableBytes) {
  EXPECT_EQ(printable("AZ\n   1\r\n"), "AZ\\n   1\\r\\n");
  EXPECT_EQ(printable("\x1b\x03\x7f"), "<ESC>^C\\x7f");
}

}  // namespace
}  // namespace fieldgate::ims
