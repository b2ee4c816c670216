// Codec vectors from shared/protocols/centent-cn0170.md §10 (numbers in the test names are the
// digest's vector numbers) and the §5 reply grammar.
#include <gtest/gtest.h>

#include "drivers/centent_cn0170/cn0170_codec.hpp"

namespace fieldgate::cn0170 {
namespace {

std::string normalised(std::string_view s) {
  std::string error;
  auto r = normalise_request(s, error);
  return r ? *r : "error: " + error;
}

TEST(Cn0170Codec, V1AutobaudReplyNamesTheUnit) {
  const auto m = parse_message("U0\r");
  EXPECT_EQ(m.kind, MessageKind::autobaud);
  EXPECT_EQ(m.subject, 0);
  EXPECT_EQ(m.unit, 0);
  // With the prefix the manual never shows (§9 #4), the unit is still the one inside.
  const auto p = parse_message("3U3\r");
  EXPECT_EQ(p.kind, MessageKind::autobaud);
  EXPECT_EQ(p.subject, 3);
  EXPECT_EQ(p.unit, 3);
}

TEST(Cn0170Codec, V3HexIsTheRawRegisterAndPassesUnchanged) {
  EXPECT_EQ(normalised("X=0FA000H"), "X=0FA000H");
  EXPECT_EQ(normalised("XV=320H"), "XV=320H");
  EXPECT_EQ(normalised("XA=0C8H"), "XA=0C8H");
  EXPECT_EQ(0xFA000, 1000 * 1024);
}

TEST(Cn0170Codec, V4PositionReplyOfPage2) {
  const auto m = parse_message("XP=00100400h");
  ASSERT_EQ(m.kind, MessageKind::position);
  EXPECT_EQ(m.key, "XP");
  EXPECT_EQ(m.values, (std::vector<int64_t>{0x100400, 0}));
  EXPECT_EQ(m.values[0] / 1024, 1025);  // steps
}

TEST(Cn0170Codec, V5RejectedStringIsEchoed) {
  const auto m = parse_message("\"XY?\" ?\r");
  ASSERT_EQ(m.kind, MessageKind::reject);
  EXPECT_EQ(m.text, "XY?");
  const auto p = parse_message("2\"xq=5\" ?");
  ASSERT_EQ(p.kind, MessageKind::reject);
  EXPECT_EQ(p.unit, 2);
  EXPECT_EQ(p.text, "xq=5");  // case as sent
  EXPECT_FALSE(classify_query("XY?"));
}

TEST(Cn0170Codec, V8OverflowWarningAndQueueEmpty) {
  EXPECT_EQ(parse_message("Q*").kind, MessageKind::queue_full);
  EXPECT_EQ(parse_message("*Q").kind, MessageKind::queue_empty);
  // p.6 once writes the queue-empty message as a bare "Q" (§9 #12).
  EXPECT_EQ(parse_message("Q").kind, MessageKind::queue_empty);
  const auto prefixed = parse_message("4Q*\r");
  EXPECT_EQ(prefixed.kind, MessageKind::queue_full);
  EXPECT_EQ(prefixed.unit, 4);
}

TEST(Cn0170Codec, V9ModeQuery) {
  const auto q = classify_query("M?");
  ASSERT_TRUE(q);
  EXPECT_EQ(q->kind, MessageKind::mode);
  const auto m = parse_message("M1");
  EXPECT_EQ(m.kind, MessageKind::mode);
  EXPECT_EQ(m.values, std::vector<int64_t>{1});
  EXPECT_EQ(parse_message("M4").kind, MessageKind::unknown);
}

TEST(Cn0170Codec, V16V18UnitListInChainOrder) {
  int expected[] = {0, 1, 5, 3};
  const char* lines[] = {"[U0]\r", " [U1]\r", "[U5]\r", "[U3]\r"};  // p.15 indents some
  for (int i = 0; i < 4; ++i) {
    const auto m = parse_message(lines[i]);
    EXPECT_EQ(m.kind, MessageKind::unit_list);
    EXPECT_EQ(m.subject, expected[i]);
  }
  EXPECT_EQ(classify_instruction(".U=0"), InstructionKind::unit_assignment);
  EXPECT_EQ(classify_instruction(".U+1=1"), InstructionKind::unit_assignment);
  EXPECT_EQ(classify_instruction(".U2=5"), InstructionKind::unit_assignment);
  EXPECT_EQ(classify_instruction(".U?"), InstructionKind::unit_command);
}

TEST(Cn0170Codec, V17SelectionBytes) {
  // 2E 55 32 0D
  EXPECT_EQ(encode_select(2), std::string("\x2e\x55\x32\x0d"));
  EXPECT_EQ(classify_instruction(".U2"), InstructionKind::unit_command);
}

TEST(Cn0170Codec, V20V21ClockReadings) {
  const auto t = parse_message("08:45.11");
  ASSERT_EQ(t.kind, MessageKind::time);
  EXPECT_EQ(t.unit, 0);
  EXPECT_EQ(t.values, (std::vector<int64_t>{8, 45, 11}));
  // A prefixed time is nine characters starting with a digit (§5).
  const auto p = parse_message("208:45.11");
  ASSERT_EQ(p.kind, MessageKind::time);
  EXPECT_EQ(p.unit, 2);
  EXPECT_EQ(p.values, (std::vector<int64_t>{8, 45, 11}));
  const auto d = parse_message("02/15/97");
  ASSERT_EQ(d.kind, MessageKind::date);
  EXPECT_EQ(d.values, (std::vector<int64_t>{2, 15, 97}));
  EXPECT_EQ(classify_query("T?")->value_count, 3);
}

TEST(Cn0170Codec, V29V30InstructionsAndLinkedForms) {
  EXPECT_EQ(split_instructions("X+100;Y+200"), (std::vector<std::string>{"X+100", "Y+200"}));
  EXPECT_EQ(split_instructions("XL+; YL+"), (std::vector<std::string>{"XL+", "YL+"}));
  EXPECT_EQ(split_instructions(";;M?; "), std::vector<std::string>{"M?"});
  EXPECT_EQ(normalised("X=2000 & Y+3.5"), "X=2000 & Y+3.5");
  EXPECT_EQ(normalised("X+.875;Y-123.45"), "X+.875;Y-123.45");
}

TEST(Cn0170Codec, V38VelocityReplyWithLeadingZero) {
  const auto m = parse_message("YV=0D485h");
  ASSERT_EQ(m.kind, MessageKind::velocity);
  EXPECT_EQ(m.key, "YV");
  EXPECT_EQ(m.values[0], 0xD485);
  EXPECT_DOUBLE_EQ(m.values[0] / 4.0, 13601.25);
  const auto v = parse_message("1XYV=0320h");
  EXPECT_EQ(v.key, "XYV");
  EXPECT_EQ(v.unit, 1);
}

TEST(Cn0170Codec, V39V46TriggersAreNotReplies) {
  const auto xv = parse_message("XV");
  EXPECT_EQ(xv.kind, MessageKind::velocity_trigger);
  EXPECT_EQ(xv.key, "X");
  const auto yp = parse_message("3YP\r");
  EXPECT_EQ(yp.kind, MessageKind::position_trigger);
  EXPECT_EQ(yp.key, "Y");
  EXPECT_EQ(yp.unit, 3);
}

TEST(Cn0170Codec, V41AccelerationReply) {
  const auto m = parse_message("XA=00BBh");
  ASSERT_EQ(m.kind, MessageKind::acceleration);
  EXPECT_EQ(m.values[0] * 64, 11968);
}

TEST(Cn0170Codec, V43ProfileReplies) {
  EXPECT_EQ(parse_message("XC=3").values, std::vector<int64_t>{3});
  EXPECT_EQ(parse_message("XC=L").values, std::vector<int64_t>{17});
  EXPECT_EQ(parse_message("XC=P").values, std::vector<int64_t>{18});
  EXPECT_EQ(parse_message("YC=U").values, std::vector<int64_t>{19});
  EXPECT_EQ(parse_message("XC=17").kind, MessageKind::profile);
  EXPECT_EQ(parse_message("XC=20").kind, MessageKind::unknown);
}

TEST(Cn0170Codec, V45PositionAtRestAndMovingCw) {
  const auto rest = parse_message("X=00C0E6B6h");
  ASSERT_EQ(rest.kind, MessageKind::position);
  EXPECT_EQ(rest.key, "XP");
  EXPECT_EQ(rest.values, (std::vector<int64_t>{0xC0E6B6, 0}));
  EXPECT_NEAR(0xC0E6B6 / 1024.0, 12345.678, 0.001);
  const auto cw = parse_message("X+00C0E6B6h");
  EXPECT_EQ(cw.values[1], kXMoving | kMoving);
  const auto ccw = parse_message("Y-00C0E6B6h");
  EXPECT_EQ(ccw.key, "YP");
  EXPECT_EQ(ccw.values[1], kYMoving | kYCounterClockwise | kMoving);
  // §2 bytes on the wire: '2' prefix, then the reply.
  const auto unit2 = parse_message("2X+00C0E6B6h\r");
  EXPECT_EQ(unit2.unit, 2);
  EXPECT_TRUE(unit2.prefixed);
  EXPECT_EQ(unit2.values[0], 0xC0E6B6);
  // Tolerated: separator after the prefix, space after '=', upper-case H, short widths.
  EXPECT_EQ(parse_message("2 X= 0C0E6B6H").values[0], 0xC0E6B6);
  EXPECT_EQ(parse_message("7:X=5h").unit, 7);
  EXPECT_EQ(parse_message("X=FFFFFFFFh").values[0], 0xFFFFFFFF);
}

TEST(Cn0170Codec, V49RatioReply) {
  const auto m = parse_message("Y/X=80000000h");
  ASSERT_EQ(m.kind, MessageKind::ratio);
  EXPECT_EQ(m.key, "Y/X");
  EXPECT_EQ(m.values[0], 0x80000000);
  EXPECT_EQ(classify_query("Y/X?")->key, "Y/X");
}

TEST(Cn0170Codec, V53InputReply) {
  EXPECT_EQ(parse_message("P1=0").values, std::vector<int64_t>{0});
  const auto on = parse_message("5P1=1");
  EXPECT_EQ(on.key, "P1");
  EXPECT_EQ(on.unit, 5);
  EXPECT_EQ(on.values, std::vector<int64_t>{1});
}

TEST(Cn0170Codec, V55AnalogReplies) {
  const auto m = parse_message("A\\X=C0h");
  ASSERT_EQ(m.kind, MessageKind::analog);
  EXPECT_EQ(m.key, "A\\X");
  EXPECT_EQ(m.values[0], 192);
  EXPECT_EQ(parse_message("A\\X= FFh").values[0], 255);
  EXPECT_EQ(parse_message("A1=80h").key, "A1");
  EXPECT_EQ(parse_message("A\\Z=80h").kind, MessageKind::unknown);
}

TEST(Cn0170Codec, V57V59AuxPortReplies) {
  EXPECT_EQ(parse_message("P= 55h").values[0], 0x55);
  EXPECT_EQ(parse_message("P= 3Ch").values[0], 0x3C);
  EXPECT_EQ(classify_query("P?")->kind, MessageKind::aux);
}

TEST(Cn0170Codec, GarbageIsUnknown) {
  EXPECT_EQ(parse_message("X=00C0E6B6").kind, MessageKind::unknown);    // no h
  EXPECT_EQ(parse_message("X=1FFFFFFFFh").kind, MessageKind::unknown);  // over 32 bits
  EXPECT_EQ(parse_message("X=h").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("\x01\xff\x7f").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("0X=5h").kind, MessageKind::unknown);  // unit 0 has no prefix
  EXPECT_EQ(parse_message("\"unterminated ?").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("\r\n").kind, MessageKind::blank);
}

// The manual prints register values in upper-case hex with a lower-case h (p.2, 35): a
// lower-case digit is a garbled character (0x41 'A' read as 0x61 'a'), not a hex digit. Seen
// served as values: 1X=001aD303h (true 0014D303) and 1 XP-00f97E0Ch.
TEST(Cn0170Codec, LowerCaseHexDigitsAreGarbled) {
  EXPECT_EQ(parse_message("1X=001aD303h").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("1 XP-00f97E0Ch").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("YV=0d485h").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("XA=00bbh").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("Y/X=8000000ah").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("A\\X=c0h").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("P= 3ch").kind, MessageKind::unknown);
  // Letters the manual prints in upper case are no more lenient.
  EXPECT_EQ(parse_message("x=00C0E6B6h").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("m1").kind, MessageKind::unknown);
  // Nor are characters around the text the manual does not print (a tab), or a profile number
  // of three digits.
  EXPECT_EQ(parse_message("\tX=00C0E6B6h").kind, MessageKind::unknown);
  EXPECT_EQ(parse_message("XC=017").kind, MessageKind::unknown);
  // The same replies as printed are values.
  EXPECT_EQ(parse_message("1X=0014D303h").values[0], 0x14D303);
  EXPECT_EQ(parse_message("1 XP-00F97E0Ch").values[0], 0xF97E0C);
}

TEST(Cn0170Codec, QueriesTheFamilyMatches) {
  EXPECT_EQ(classify_query("xp?")->key, "XP");  // letters are case-insensitive (p.2)
  EXPECT_EQ(classify_query("XP?")->value_count, 2);
  EXPECT_TRUE(classify_query("XP?")->hex);
  EXPECT_FALSE(classify_query("XC?")->hex);
  EXPECT_EQ(classify_query("A\\Y?")->key, "A\\Y");
  EXPECT_FALSE(classify_query("XP"));
  EXPECT_FALSE(classify_query(".U?"));
  EXPECT_EQ(values_of_request({*classify_query("XP?"), *classify_query("YP?")}), 5);
  EXPECT_EQ(values_of_request({*classify_query("P1?"), *classify_query("P2?")}), 2);
}

TEST(Cn0170Codec, InstructionKinds) {
  EXPECT_EQ(classify_instruction("K"), InstructionKind::kill);
  EXPECT_EQ(classify_instruction("q"), InstructionKind::quit);
  EXPECT_EQ(classify_instruction("H"), InstructionKind::halt);
  EXPECT_EQ(classify_instruction("M2"), InstructionKind::mode_program);
  EXPECT_EQ(classify_instruction("M1"), InstructionKind::mode_immediate);
  EXPECT_EQ(classify_instruction("M1\\-"), InstructionKind::other);
  EXPECT_EQ(classify_instruction("X=1000"), InstructionKind::other);
  EXPECT_EQ(classify_instruction("XP?"), InstructionKind::query);
}

TEST(Cn0170Codec, RewritesForNumericRegisters) {
  EXPECT_EQ(normalised("XC17"), "XC\\L");
  EXPECT_EQ(normalised("YC18"), "YC\\P");
  EXPECT_EQ(normalised("XC19"), "XC\\U");
  EXPECT_EQ(normalised("XC7"), "XC7");
  EXPECT_EQ(normalised("XC20"),
            "error: 'XC20': profile must be 1..16, 17 (linear), 18 "
            "(parabolic) or 19 (user)");
  EXPECT_EQ(normalised("XH1;YH0"), "XH+;YH-");
  EXPECT_EQ(normalised("XP1;XV0;XL1;XM0;XB1"), "XP+;XV-;XL+;XM-;XB+");
  EXPECT_EQ(normalised("XR10;YR125"), "XR10;YR125");
  EXPECT_EQ(normalised("XR3"), "error: 'XR3': step resolution must be 1, 2, 10 or 125");
  // Signed distances from a setpoint.
  EXPECT_EQ(normalised("X+0FFFFFC00H"), "X-0400H");
  EXPECT_EQ(normalised("X+080000000H"), "X-080000000H");
  EXPECT_EQ(normalised("X+07FFFFFFFH"), "X+07FFFFFFFH");
  EXPECT_EQ(normalised("X+-5.5"), "X-5.5");
  EXPECT_EQ(normalised("XV=200,2000;X+0FFFFFC00H,Y+0400H"), "XV=200,2000;X-0400H,Y+0400H");
  // Not distances: speed control, ratio enable, triggers, positions.
  EXPECT_EQ(normalised("X++500;X--;Y/X+;XP+;XP=0FFFFFC00H"),
            "error: 'XP=0FFFFFC00H': a negative absolute position; the CN0170's position "
            "register takes only positive numbers (manual p.35) and the axis would run the other "
            "way (p.21)");
  EXPECT_EQ(normalised("X++500;X--;Y/X+;XP+;XP=0400H"), "X++500;X--;Y/X+;XP+;XP=0400H");
}

// Set Position (p.35): the register takes only positive numbers; X=n runs CW when n is greater
// than the register (p.21). A negative int32 target rendered as hex is never sent.
TEST(Cn0170Codec, NegativeAbsolutePositionsAreRefused) {
  const std::string why =
      ": a negative absolute position; the CN0170's position register takes only positive "
      "numbers (manual p.35) and the axis would run the other way (p.21)";
  EXPECT_EQ(normalised("XV=200,2000;X=0FFFFD800H"), "error: 'X=0FFFFD800H'" + why);
  EXPECT_EQ(normalised("Y=080000000H"), "error: 'Y=080000000H'" + why);
  EXPECT_EQ(normalised("XP=0FFFFFC00H"), "error: 'XP=0FFFFFC00H'" + why);
  EXPECT_EQ(normalised("X=-5"), "error: 'X=-5'" + why);
  EXPECT_EQ(normalised("XYV=200,2000;X=0400H,Y=0FFFFFC00H"), "error: 'Y=0FFFFFC00H'" + why);
  EXPECT_EQ(normalised("X=2000 & Y=-3.5"), "error: 'Y=-3.5'" + why);
  // Zero and positive positions, relative moves, ratio and velocity registers pass.
  EXPECT_EQ(normalised("X=00H;XP=0H;Y=07FFFFFFFH"), "X=00H;XP=0H;Y=07FFFFFFFH");
  EXPECT_EQ(normalised("X+0FFFFD800H"), "X-02800H");
  EXPECT_EQ(normalised("Y/X=0C0000000H;XYV=0FFFFH"), "Y/X=0C0000000H;XYV=0FFFFH");
}

TEST(Cn0170Codec, UnitAddresses) {
  std::string error;
  for (int u = 0; u <= 9; ++u) EXPECT_EQ(parse_unit_address(std::to_string(u), error), u);
  for (const char* bad : {"10", "a", "", "-1", "1.5"}) {
    EXPECT_FALSE(parse_unit_address(bad, error)) << bad;
    EXPECT_NE(error.find("0..9"), std::string::npos);
  }
}

TEST(Cn0170Codec, LinesEndAtCrOrLf) {
  EXPECT_EQ(frame_length("X=1h"), 0u);
  EXPECT_EQ(frame_length("X=1h\r\nY=2h\r"), 5u);
  EXPECT_EQ(frame_length("\nY=2h\r"), 1u);
  EXPECT_EQ(frame_length("M1\n"), 3u);
}

}  // namespace
}  // namespace fieldgate::cn0170
