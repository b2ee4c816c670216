// Vectors from shared/protocols/copley-ascii.md §3 ("Every command-level transcript") and §2.
#include <gtest/gtest.h>

#include <ostream>

#include "drivers/copley_ascii/copley_codec.hpp"

namespace fieldgate::copley {
namespace {

TEST(CopleyEncode, NodeZeroHasNoPrefix) {
  EXPECT_EQ(encode_command(0, 0, "g r0x30"), "g r0x30\r");
  EXPECT_EQ(encode_command(0, 0, "s r0x30 1200"), "s r0x30 1200\r");
  EXPECT_EQ(encode_command(0, 0, "t 1"), "t 1\r");
}

TEST(CopleyEncode, ForwardedNodeGetsIdAndOneSpace) {
  EXPECT_EQ(encode_command(8, 0, "i r0"), "8 i r0\r");  // §2.7
  EXPECT_EQ(encode_command(127, 0, "g r0xa0"), "127 g r0xa0\r");
}

TEST(CopleyEncode, AxisSyntax) {
  EXPECT_EQ(encode_command(0, 'b', "g r0x32"), ".b g r0x32\r");   // §2.8
  EXPECT_EQ(encode_command(2, 'c', "g r0x32"), "2.c g r0x32\r");  // §2.8
}

TEST(CopleyFrame, WaitsForCarriageReturn) {
  EXPECT_EQ(frame_length(""), 0u);
  EXPECT_EQ(frame_length("v 12"), 0u);
  EXPECT_EQ(frame_length("v 1200\r"), 7u);
  EXPECT_EQ(frame_length("ok\rv 1\r"), 3u);
}

struct ReplyVector {
  const char* line;
  ParsedReply::Kind kind;
  std::vector<int64_t> values;
};

// The line as ctest shows it, CR and LF spelt out (the struct's bytes hold a pointer).
void PrintTo(const ReplyVector& v, std::ostream* os) {
  for (const char* c = v.line; *c; ++c) {
    if (*c == '\r')
      *os << "<CR>";
    else if (*c == '\n')
      *os << "<LF>";
    else
      *os << *c;
  }
}

class CopleyReplyTranscripts : public ::testing::TestWithParam<ReplyVector> {};

TEST_P(CopleyReplyTranscripts, Parse) {
  const auto& v = GetParam();
  const auto r = parse_reply(v.line);
  EXPECT_EQ(r.kind, v.kind) << v.line;
  EXPECT_EQ(r.values, v.values) << v.line;
}

INSTANTIATE_TEST_SUITE_P(
    Manual, CopleyReplyTranscripts,
    ::testing::Values(
        ReplyVector{"ok\r", ParsedReply::Kind::ok, {}},                  // §2.2 s r0x30 1200
        ReplyVector{"e 33\r", ParsedReply::Kind::error, {33}},           // §2.2 s r 0x30 1000
        ReplyVector{"v 1200\r", ParsedReply::Kind::values, {1200}},      // §2.3 g r0x30
        ReplyVector{"e 15\r", ParsedReply::Kind::error, {15}},           // §2.3 g f0x17
        ReplyVector{"r 15\r", ParsedReply::Kind::register_value, {15}},  // §2.7 i r0
        ReplyVector{"r 35\r", ParsedReply::Kind::register_value, {35}},  // §2.7 8 i r0
        ReplyVector{"v1200\r", ParsedReply::Kind::values, {1200}},       // §2.8 no space
        ReplyVector{"v 134217728\r", ParsedReply::Kind::values, {134217728}},  // §3.4.2 0xa0
        ReplyVector{"v -7936 200 0 775 1550 775 -12774 32763 5813\r",          // §4.2.4 0x6b
                    ParsedReply::Kind::values,
                    {-7936, 200, 0, 775, 1550, 775, -12774, 32763, 5813}},
        ReplyVector{"v 258 0\r", ParsedReply::Kind::values, {258, 0}},  // 0x70-0x77 pairs
        ReplyVector{"\nv 4096\r", ParsedReply::Kind::values, {4096}},   // stray LF
        ReplyVector{"e32\r", ParsedReply::Kind::error, {32}}));         // optional space

TEST(CopleyReply, MalformedIsNeverTakenForAValue) {
  for (const char* bad : {"", "\r", "x\r", "v\r", "v \r", "v 12a\r", "e\r", "e 1 2\r", "okay\r",
                          "r\r", "vv 1\r", "v 0x\r", "\x7f\xff\r",
                          // Issue 26: only what the transcripts allow.
                          "v 1  2\r", "v\t5\r", "v 5\t\r", " v 5\r", "v  5\r", "v 5 \r", "v 0X1F\r",
                          "v 99999999999999999999\r", "v 1,2\r", "ok \r"}) {
    const auto r = parse_reply(bad);
    EXPECT_EQ(r.kind, ParsedReply::Kind::malformed) << "'" << bad << "'";
  }
}

TEST(CopleyErrors, ManualTextsAndUnknownCodes) {
  EXPECT_EQ(error_text(33), "ASCII command parsing error");
  EXPECT_EQ(error_text(32), "CAN Network communications failure");
  EXPECT_EQ(error_text(15), "Variable doesn't exist on requested page");
  EXPECT_EQ(error_text(2), "unknown error code");  // not listed in App. E
  EXPECT_EQ(error_text(99), "unknown error code");
}

TEST(CopleyAddress, ParsesConfigForms) {
  std::string error;
  auto a = parse_address("0", error);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->node, 0);
  EXPECT_EQ(a->axis, 0);
  a = parse_address("127", error);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->node, 127);
  a = parse_address("2.c", error);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->node, 2);
  EXPECT_EQ(a->axis, 'c');
  for (const char* bad : {"128", "-1", "x", "2.d", "2.", "", "3 ", "0x5"}) {
    EXPECT_FALSE(parse_address(bad, error)) << bad;
    EXPECT_FALSE(error.empty());
  }
}

}  // namespace
}  // namespace fieldgate::copley
