// Codec vectors from shared/protocols/techno-cseries.md §11 (and the sections they refer to).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "drivers/techno_c/techno_codec.hpp"

namespace fieldgate::techno {
namespace {

// §11.1: every host line is `@0…` plus CR, in the canonical form (no spaces).
TEST(TechnoEncode, ImmediateTranscriptLines) {
  struct Line {
    const char* command;
    const char* wire;
    const char* vector;  // §11.1 number
  };
  for (const Line& line : std::vector<Line>{
           {"A400,9000", "@0A400,9000\r", "#1"},
           {"A300,1200,400,5000", "@0A300,1200,400,5000\r", "#2"},
           {"7", "@07\r", "#4"},
           {"R7", "@0R7\r", "#4, #6"},
           {"M2700,3000,2000,2000,350,1000,0,1000", "@0M2700,3000,2000,2000,350,1000,0,1000\r",
            "#4"},
           {"Y9599,1000,314,7360,1972,-1,1", "@0Y9599,1000,314,7360,1972,-1,1\r", "#5"},
           {"f-1", "@0f-1\r", "#5"},
           {"r2", "@0r2\r", "#7"},
           {"P", "@0P\r", "#8"},
           {"b4711", "@0b4711\r", "#11"},
           {"B33211,128", "@0B33211,128\r", "#12"},
           {"d3000,4000,250", "@0d3000,4000,250\r", "#15"},
           {"n3", "@0n3\r", "#17"},
           {"z1", "@0z1\r", "#18"},
           {"k", "@0k\r", "#19"},
       }) {
    SCOPED_TRACE(std::string(line.vector) + ": " + line.command);
    EXPECT_EQ(encode_command(0, line.command), line.wire);
  }
}

TEST(TechnoEncode, RawBytesHaveNoPrefixAndNoCr) {
  // #21: 0xFE reset; 0xFF stop, twice (a buffered command would start otherwise, p.73).
  EXPECT_EQ(encode_command(0, kStopCommand), std::string("\xff\xff"));
  EXPECT_EQ(encode_command(5, kStopCommand, 1), std::string("\xff"));
  EXPECT_EQ(encode_command(0, kResetCommand), std::string("\xfe"));
}

// Each command classifies with the expected value in one field of Command; a failing row names
// the command.
template <class Value>
void expect_classified(Value Command::*field,
                       const std::vector<std::pair<const char*, Value>>& cases) {
  for (const auto& [command, expected] : cases) {
    SCOPED_TRACE(command);
    EXPECT_EQ(classify(command).*field, expected);
  }
}

TEST(TechnoClassify, CaseDecidesWhenTheHandshakeComes) {
  const std::vector<std::pair<const char*, Handshake>> handshakes = {
      {"A400,9000", Handshake::at_end}, {"a400,9000", Handshake::at_start},
      {"m1,30", Handshake::at_start},   {"R7", Handshake::at_end},
      {"r2", Handshake::at_start},      {"S", Handshake::at_end},
      {"s", Handshake::at_start},       {"Y9599,1000,314,7360,1972,-1,1", Handshake::at_end},
      {"P", Handshake::immediate},      {"n7", Handshake::immediate},
  };
  expect_classified(&Command::handshake, handshakes);
  const std::vector<std::pair<const char*, CommandKind>> kinds = {
      {"M1,30", CommandKind::move_absolute}, {"7", CommandKind::specify_axes},
      {"b65531", CommandKind::peek},         {"c2048", CommandKind::peek},
      {"<stop>", CommandKind::stop},         {"<reset>", CommandKind::reset},
      {"X1", CommandKind::unknown},          {"", CommandKind::unknown},
  };
  expect_classified(&Command::kind, kinds);
  EXPECT_EQ(classify("7").values, "7");
}

TEST(TechnoValues, ToleratesTheManualsSpacing) {
  // §3: the manual mixes commas, comma + space and signs.
  EXPECT_EQ(parse_values("400, 9000"), (std::vector<int64_t>{400, 9000}));
  EXPECT_EQ(parse_values("-2700,3000,0,2000,350,1000,-350,1000"),
            (std::vector<int64_t>{-2700, 3000, 0, 2000, 350, 1000, -350, 1000}));
  EXPECT_EQ(parse_values("+5"), (std::vector<int64_t>{5}));
  EXPECT_EQ(parse_values(""), std::vector<int64_t>{});
  EXPECT_FALSE(parse_values("1,,2"));
  EXPECT_FALSE(parse_values("1;2"));
  EXPECT_FALSE(parse_values("0x10"));
}

TEST(TechnoAxes, ValueCountsAndMasks) {
  // §2: 1 axis 2 values, XY 4, XYZ 8, XZ 6 [inf].
  EXPECT_EQ(move_value_count(1), 2);
  EXPECT_EQ(move_value_count(3), 4);
  EXPECT_EQ(move_value_count(5), 6);
  EXPECT_EQ(move_value_count(7), 8);
  EXPECT_EQ(move_value_count(2), 0);
  for (int a : {1, 3, 5, 7}) EXPECT_TRUE(valid_axes_definition(a)) << a;
  for (int a : {0, 2, 4, 6, 8}) EXPECT_FALSE(valid_axes_definition(a)) << a;
  EXPECT_TRUE(valid_axis_mask(7, 7));
  EXPECT_TRUE(valid_axis_mask(4, 5));
  EXPECT_FALSE(valid_axis_mask(2, 5));  // Y is not defined with XZ
  EXPECT_FALSE(valid_axis_mask(0, 7));
  EXPECT_FALSE(valid_axis_mask(8, 7));
}

// §11.3 parsing vectors.
TEST(TechnoPositions, ManualExample) {
  const auto r = parse_positions("000010002000FFFFFE");  // §11.1 #8
  ASSERT_EQ(r.kind, ParsedReply::Kind::ok);
  EXPECT_EQ(r.values, (std::vector<int64_t>{16, 8192, -2}));
}

TEST(TechnoPositions, TwentyFourBitTwosComplement) {
  EXPECT_EQ(sign_extend_24(0x7FFFFF), 8388607);
  EXPECT_EQ(sign_extend_24(0x800000), -8388608);
  EXPECT_EQ(sign_extend_24(0xFFFFFF), -1);
  // The hex lesson: 8F, 230F, FA2D are 143, 8975, 64045 (the manual prints 65533 for FA2D).
  EXPECT_EQ(sign_extend_24(0x8F), 143);
  EXPECT_EQ(sign_extend_24(0x230F), 8975);
  EXPECT_EQ(sign_extend_24(0xFA2D), 64045);
  const auto r = parse_positions("7FFFFF800000FFFFFF");
  ASSERT_EQ(r.kind, ParsedReply::Kind::ok);
  EXPECT_EQ(r.values, (std::vector<int64_t>{8388607, -8388608, -1}));
}

TEST(TechnoPositions, TolerantOfHandshakeTerminatorAndCase) {
  // §5 robust parse: a leading 0 handshake, CR/LF, lower-case hex.
  for (const char* reply : {"0000010002000FFFFFE", "000010002000FFFFFE\r",
                            "0000010002000FFFFFE\r\n", "000010002000fffffe"}) {
    const auto r = parse_positions(reply);
    ASSERT_EQ(r.kind, ParsedReply::Kind::ok) << reply;
    EXPECT_EQ(r.values, (std::vector<int64_t>{16, 8192, -2})) << reply;
  }
  // Fewer axes fitted (the model's fitted_axes): 6 or 12 digits, fields stay X Y Z.
  const auto one = parse_positions("000010\r", 1);
  ASSERT_EQ(one.kind, ParsedReply::Kind::ok);
  EXPECT_EQ(one.values, (std::vector<int64_t>{16, 0, 0}));
  const auto two = parse_positions("0000010002000", 2);
  ASSERT_EQ(two.kind, ParsedReply::Kind::ok);
  EXPECT_EQ(two.values, (std::vector<int64_t>{16, 8192, 0}));
  EXPECT_EQ(parse_positions("000010002000FFFFFE", 1).values, (std::vector<int64_t>{16, 8192, -2}));
}

// Found by the Techno grammar of fuzz_serial_codecs (at once, on `000010` CR for a three-axis
// controller): a `@0P` reply cut short, e.g. by an idle gap ("000010002000", the `FFFFFE` of Z
// still on its way), was served with Z = 0, a position the controller never sent. The manual gives
// "eighteen characters" (p.43); a shorter reply is taken only from a controller with fewer axes
// fitted, and only at its length.
TEST(TechnoPositions, AReplyCutShortIsNoPosition) {
  for (const char* cut : {"000010002000", "0000010002000", "000010\r", "0000010", "000010002000\r"})
    EXPECT_EQ(parse_positions(cut).kind, ParsedReply::Kind::malformed) << cut;
  EXPECT_EQ(parse_positions("0000010", 2).kind, ParsedReply::Kind::malformed);
  EXPECT_EQ(parse_positions("000010002000", 1).kind, ParsedReply::Kind::malformed);
}

TEST(TechnoPositions, ErrorsAndGarbage) {
  const auto error = parse_positions("4");
  EXPECT_EQ(error.kind, ParsedReply::Kind::error);
  EXPECT_EQ(error.code, '4');
  EXPECT_EQ(parse_positions("\r").kind, ParsedReply::Kind::error);  // unexpected end of command
  for (const char* garbage :
       {"0", "00001000200", "00001000200XFFFFFE", "000010002000FFFFFE000001", ""})
    EXPECT_EQ(parse_positions(garbage).kind, ParsedReply::Kind::malformed) << garbage;
}

TEST(TechnoPeek, HandshakeThenTwoHexDigits) {
  const auto r = parse_peek("08F");  // §11.1 #11: `0` + 2 hex digits
  ASSERT_EQ(r.kind, ParsedReply::Kind::ok);
  EXPECT_EQ(r.values, std::vector<int64_t>{143});
  EXPECT_EQ(parse_peek("0ff\r").values, std::vector<int64_t>{255});
  EXPECT_EQ(parse_peek("5").kind, ParsedReply::Kind::error);
  EXPECT_EQ(parse_peek("8F").kind, ParsedReply::Kind::malformed);
  EXPECT_EQ(parse_peek("0").kind, ParsedReply::Kind::malformed);
}

TEST(TechnoHandshake, EveryCharacterOfTheManual) {
  EXPECT_EQ(parse_handshake("0").kind, ParsedReply::Kind::ok);
  // §11.3: `5` syntax error, `D` illegal speed, CR unexpected end of command; §6 the rest.
  for (const char c : std::string("2345678BcDGz\r")) {
    const auto r = parse_handshake(std::string(1, c));
    EXPECT_EQ(r.kind, ParsedReply::Kind::error) << int(c);
    EXPECT_EQ(r.code, c);
  }
  EXPECT_EQ(error_text('5'), "syntax error (or an illegal step count or sign)");
  EXPECT_EQ(error_text('D'), "illegal speed (valid 30..10000 steps/s)");
  EXPECT_EQ(error_text('\r'), "unexpected end of command");
  EXPECT_EQ(error_text('B'), error_text('8'));  // p.77 calls illegal branch B
  EXPECT_EQ(describe_error('7'),
            "'7' (55): illegal parameters (or a value count that does not fit the defined axes)");
  EXPECT_EQ(describe_error('\r').substr(0, 9), "'CR' (13)");
  // The manual's letter O is a misprint for the digit 0 (§8.12): not an acknowledge.
  EXPECT_EQ(parse_handshake("O").kind, ParsedReply::Kind::malformed);
  EXPECT_EQ(parse_handshake("00").kind, ParsedReply::Kind::malformed);
}

TEST(TechnoFrames, Handshake) {
  EXPECT_EQ(handshake_frame(""), 0u);
  EXPECT_EQ(handshake_frame("0"), 1u);
  EXPECT_EQ(handshake_frame("0\r\n"), 1u);
}

TEST(TechnoFrames, PositionReplyModes) {
  const std::string bare = "000010002000FFFFFE";
  // A CR ends the reply in every mode.
  for (auto mode : {PositionReply::automatic, PositionReply::bare, PositionReply::ack})
    EXPECT_EQ(position_frame(bare + "\r", mode), 19u);
  // Without a CR: bare knows 18, ack knows 19; auto waits for a 19th or the idle gap.
  EXPECT_EQ(position_frame(bare, PositionReply::bare), 18u);
  EXPECT_EQ(position_frame(bare, PositionReply::automatic), 0u);
  EXPECT_EQ(position_frame("0" + bare, PositionReply::automatic), 19u);
  EXPECT_EQ(position_frame("0" + bare, PositionReply::ack), 19u);
  // An error character: at once in ack mode, and for the ones that are no hex digit.
  EXPECT_EQ(position_frame("4", PositionReply::ack), 1u);
  EXPECT_EQ(position_frame("4", PositionReply::automatic), 0u);
  EXPECT_EQ(position_frame("G", PositionReply::automatic), 1u);
  EXPECT_EQ(position_frame("\r", PositionReply::automatic), 1u);
  EXPECT_EQ(position_frame("", PositionReply::automatic), 0u);
}

TEST(TechnoFrames, Peek) {
  EXPECT_EQ(peek_frame("0F"), 0u);
  EXPECT_EQ(peek_frame("0FF"), 3u);
  EXPECT_EQ(peek_frame("0FF\r"), 4u);  // the CR goes with the reply
  EXPECT_EQ(peek_frame("5"), 1u);
  EXPECT_EQ(peek_frame("0\r"), 2u);
}

TEST(TechnoTiming, LegFormulaOfTheDigest) {
  // a = 75 Hz/ms = 75000 steps/s²; 9000 steps at 9000 steps/s reaches speed (d >= v²/a).
  EXPECT_NEAR(leg_seconds(9000, 9000, 75000), 1.0 + 0.12, 1e-9);
  // 400 steps at 9000: never reaches speed, 2 sqrt(d/a).
  EXPECT_NEAR(leg_seconds(400, 9000, 75000), 2 * std::sqrt(400.0 / 75000), 1e-9);
  EXPECT_EQ(leg_seconds(0, 9000, 75000), 0);
  EXPECT_NEAR(leg_seconds(-9000, 9000, 75000), 1.12, 1e-9);
}

TEST(TechnoTiming, RelativeMoveRunsPlanePairThenZ1ThenZ2) {
  MotionContext c;
  c.axes = 7;
  c.acceleration = 75000;
  c.position = {0, 0, 0};
  // §11.1 #9: X -2700 at 3000 with Y 0, then Z +350 at 1000, then Z -350 at 1000.
  const auto e = estimate_motion(classify("A-2700,3000,0,2000,350,1000,-350,1000"),
                                 {-2700, 3000, 0, 2000, 350, 1000, -350, 1000}, c);
  ASSERT_TRUE(e);
  const double expected = leg_seconds(2700, 3000, 75000) + 2 * leg_seconds(350, 1000, 75000);
  EXPECT_NEAR(e->seconds, expected, 1e-9);
  EXPECT_EQ(e->end_position[0], -2700);
  EXPECT_EQ(e->end_position[1], 0);
  EXPECT_EQ(e->end_position[2], 0);
}

TEST(TechnoTiming, AbsoluteMoveFromKnownAndUnknownStart) {
  MotionContext c;
  c.axes = 7;
  c.position = {1000, 2000, 0};
  c.travel = {10000, 10000, 10000};
  // §11.1 #4: M2700,3000,2000,2000,350,1000,0,1000 — Y stays, Z down to 350 and back to 0.
  const std::vector<int64_t> v{2700, 3000, 2000, 2000, 350, 1000, 0, 1000};
  const auto known = estimate_motion(classify("M"), v, c);
  ASSERT_TRUE(known);
  EXPECT_NEAR(known->seconds, leg_seconds(1700, 3000, 75000) + 2 * leg_seconds(350, 1000, 75000),
              1e-9);
  EXPECT_EQ(known->end_position[0], 2700);
  EXPECT_EQ(known->end_position[2], 0);
  c.position = {};
  const auto unknown = estimate_motion(classify("M"), v, c);
  ASSERT_TRUE(unknown);
  // Unknown start: as if the axis stood at the far end of its travel.
  EXPECT_NEAR(unknown->seconds,
              std::max(leg_seconds(12700, 3000, 75000), leg_seconds(12000, 2000, 75000)) +
                  leg_seconds(10350, 1000, 75000) + leg_seconds(350, 1000, 75000),
              1e-9);
}

TEST(TechnoTiming, HomingFromTravelAndHomeSpeeds) {
  MotionContext c;
  c.axes = 7;
  c.travel = {20000, 10000, 5000};
  c.home_speed = {2000, 4000, 1000};
  const auto e = estimate_motion(classify("R7"), {7}, c);
  ASSERT_TRUE(e);
  EXPECT_NEAR(e->seconds,
              leg_seconds(20000, 2000, 75000) + leg_seconds(10000, 4000, 75000) +
                  leg_seconds(5000, 1000, 75000),
              1e-9);
  EXPECT_EQ(e->end_position[0], 0);
  const auto x_only = estimate_motion(classify("R1"), {1}, c);
  ASSERT_TRUE(x_only);
  EXPECT_NEAR(x_only->seconds, leg_seconds(20000, 2000, 75000), 1e-9);
  EXPECT_EQ(e->end_position[1], 0);
}

TEST(TechnoTiming, PlaneChangesWhichAxisAPairDrives) {
  // p.58 e2 example: pairs drive Y, Z, then X twice.
  EXPECT_EQ(pair_axes(7, 2), (std::vector<int>{1, 2, 0, 0}));
  EXPECT_EQ(pair_axes(7, 0), (std::vector<int>{0, 1, 2, 2}));
  EXPECT_EQ(pair_axes(5, 0), (std::vector<int>{0, 2, 2}));
  EXPECT_EQ(pair_axes(1, 0), (std::vector<int>{0}));
}

TEST(TechnoTiming, WrongValueCountIsNoEstimate) {
  MotionContext c;
  c.axes = 3;
  EXPECT_FALSE(estimate_motion(classify("A400,9000"), {400, 9000}, c));
  EXPECT_FALSE(estimate_motion(classify("P"), {}, c));
}

TEST(TechnoAddress, OneDigitDeviceNumber) {
  std::string error;
  EXPECT_EQ(parse_device("0", error), 0);
  EXPECT_EQ(parse_device("9", error), 9);
  EXPECT_FALSE(parse_device("10", error));
  EXPECT_NE(error.find("one digit"), std::string::npos);
  EXPECT_FALSE(parse_device("a", error));
  EXPECT_FALSE(parse_device("", error));
}

}  // namespace
}  // namespace fieldgate::techno
