// Codec vectors from shared/protocols/whedco-cmc.md §10 (address 4, every host line followed by
// CR and answered `*`) and the reply variants the family tolerates.
#include <gtest/gtest.h>

#include <initializer_list>
#include <sstream>
#include <string_view>

#include "drivers/whedco_cmc/whedco_codec.hpp"

namespace fieldgate::whedco {
namespace {

std::vector<std::string> words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> out;
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

std::string wire(std::string_view command, int unit_ratio) {
  std::string error;
  const auto p = prepare_command(command, error);
  EXPECT_TRUE(p) << command << ": " << error;
  return p ? wire_command(*p, unit_ratio) : std::string{};
}

std::string refusal(std::string_view command) {
  std::string error;
  EXPECT_FALSE(prepare_command(command, error)) << command;
  return error;
}

struct Refusal {
  std::string_view command;
  std::string_view reason;  // a part of the error text
};

void expect_refusals(std::initializer_list<Refusal> cases) {
  for (const auto& c : cases)
    EXPECT_NE(refusal(c.command).find(c.reason), std::string::npos) << c.command;
}

TEST(WhedcoAddress, DigitAndCommunicationFormat) {
  std::string error;
  auto a = parse_address("4", error);
  ASSERT_TRUE(a);
  EXPECT_EQ(a->unit, 4);
  EXPECT_EQ(a->mode, EchoMode::automatic);
  EXPECT_EQ(parse_address("0/echo", error)->mode, EchoMode::echo);
  EXPECT_EQ(parse_address("7/non-echo", error)->mode, EchoMode::non_echo);
  EXPECT_EQ(parse_address("5/auto", error)->mode, EchoMode::automatic);
  EXPECT_FALSE(parse_address("8", error));
  EXPECT_NE(error.find("0..7"), std::string::npos) << error;
  EXPECT_FALSE(parse_address("44", error));
  EXPECT_FALSE(parse_address("", error));
  EXPECT_FALSE(parse_address("A", error));
  EXPECT_FALSE(parse_address("4/noecho", error));
  EXPECT_NE(error.find("non-echo"), std::string::npos) << error;
}

// Q1 (§5.3.1): `4AMX?` returns the X absolute-move value.
TEST(WhedcoVectors, Q1QueryIsAddressedAndTerminated) {
  EXPECT_EQ(encode_command(4, "AMX?"), "4AMX?\r");
  std::string error;
  const auto p = prepare_command("AMX?", error);
  ASSERT_TRUE(p);
  EXPECT_TRUE(p->scaled_reply);
  EXPECT_EQ(p->quantity, Quantity::length);
  EXPECT_EQ(p->axis, 'X');
}

// Q2 (§5.11.3): a variable operand is internal units and goes unconverted.
TEST(WhedcoVectors, Q2VariableLoadIsNotScaled) {
  EXPECT_EQ(wire("VXV1", 1000), "VXV1");
  EXPECT_EQ(wire("AMXV3", 1000), "AMXV3");
}

// Q3 (§5.13.3): V1=PHE then V1=?.
TEST(WhedcoVectors, Q3VariableAssignmentAndQuery) {
  EXPECT_EQ(wire("V1=PHE", 7), "V1=PHE");
  std::string error;
  const auto q = prepare_command("V1=?", error);
  ASSERT_TRUE(q);
  EXPECT_EQ(q->quantity, Quantity::none);
  EXPECT_EQ(encode_command(4, "V1=?"), "4V1=?\r");
}

// The §10 transcripts: every line the gateway may send goes out as the manual prints it when
// the unit ratio is 1 (internal = user units); the definition lines (DEn, ED) are refused.
TEST(WhedcoVectors, TranscriptLinesAtUnitRatioOne) {
  const std::vector<std::string> transcripts = {
      "4DE2 4ACX20 4VX5 4IMX10 4RIX 4ED 4GT2",
      "4DE3 4ACX20 4ACY20 4ACW20 4ACZ20 4VX2 4VW4 4STZX 4STZY 4STZW 4STZZ 4AMX5 4AMY5 4AMW10 "
      "4AMZ10 4RAXYWZ 4ED 4GT3",
      "4DE4 4ACX30 4ACY30 4VX5 4RX2 4CRX 4ED 4GT4",
      "4DE6 4ACX20 4ACY20 4VX5 4IMX2 4IMY2 4RX2 4RRX 4ED 4GT6",
      "4DE7 4ACX20 4ACY20 4VX5 4RX-2 4IMX-2 4IMY2 4RRX 4IMX2 4RRX 4IMY-2 4RRX 4IMX-2 4RRX 4ED "
      "4GT7",
      "4DE8 4ACX20 4ACY20 4ACZ20 4VX3 4VW3 4RX2 4RW0 4IMX2 4IMY-2 4IMZ4 4RRA 4IMY2 4RRA 4ED 4GT8",
      "4DE10 4FSX5 4LIXF 4LMXN1 4AEX1 4ED 4GT10",
      "4DE11 4FSX1 4LIXF 4LMXA1 4FSY1 4LIYF 4LMYA2 4AEX1 4AEY1 4ED 4GT11",
      "4DE13 4ACX20 4ACY20 4V1=25000 4V2=2047 4V3=A1*V1 4V3=V3/V2 4V4=A2*V1 4V4=V4/V2 4RXV3 "
      "4VXV4 4CRX 4RM9 4ED 4GT13",
      "4DE14 4V1=10 4V2=50 4V3=T1*V1 4V3=V3+T2 4V3=V3*V1 4V3=V3+T3 4V3=V3*V1 4V3=V3+T4 "
      "4V3=V3*V2 4ED",
      "4DE15 4ACX20 4VX5 4GS14 4AMXV3 4RAX 4ED 4GT15",
      "4DE16 4LMXV0 4ED",
      "4DE18 4SPH 4PHO0 4LIXE1 4V0=51 4LMXV0 4AEX1 4UE1 4ED",
      "4PTA01BX10 4PTA01EX11",
      "4PTA01BX10 4PTA02BX11 4SPAXAYA",
      "4DE21 4WTENI5 4WTEI5 4RM9 4ED 4GT21",
      "4IFI9AB3GT5 4IFV1>V3GS6 4WTENI2ANI3 4VOX5 4VOX0 4HT 4WB 4EB 4GT20",
  };
  for (const auto& t : transcripts) {
    for (const auto& w : words(t)) {
      ASSERT_EQ(w.front(), '4');
      const std::string command = w.substr(1);
      std::string error;
      const auto p = prepare_command(command, error);
      if (command.starts_with("DE") || command == "ED") {
        EXPECT_FALSE(p) << command;
        continue;
      }
      ASSERT_TRUE(p) << command << ": " << error;
      EXPECT_EQ(wire_command(*p, 1), command);
      EXPECT_EQ(encode_command(4, wire_command(*p, 1)), w + "\r");
    }
  }
}

// E1, E5, E12, E17, E19 enter fractions of a user unit. With a unit ratio the gateway writes
// internal pulses and the family prints the user value.
TEST(WhedcoVectors, FractionalUserUnitsFromInternalPulses) {
  EXPECT_EQ(wire("FSX500", 1000), "FSX0.5");  // E1 4FSX.5 at 1000 pp/unit
  EXPECT_EQ(wire("AMX12500", 1000), "AMX12.5");
  EXPECT_EQ(wire("AMX-1", 3), "AMX-0.3333");  // 4 decimals for lengths
  EXPECT_EQ(wire("AMX2", 3), "AMX0.6667");
  EXPECT_EQ(wire("VX1001", 100), "VX10.01");   // 2 decimals for velocities
  EXPECT_EQ(wire("VX1", 1000), "VX0");         // below the entry resolution
  EXPECT_EQ(wire("ACX80500", 1000), "ACX81");  // whole user units for accelerations
  EXPECT_EQ(wire("ACX80000", 1), "ACX80000");
  EXPECT_EQ(wire("STPX-2500", 1000), "STPX-2.5");
  EXPECT_EQ(wire("IMX+10", 1), "IMX10");
  EXPECT_EQ(wire("SHPX0", 1000), "SHPX0");
  EXPECT_EQ(wire("RW1500", 1000), "RW1.5");  // W/Z pair: unit ratio of W
  EXPECT_EQ(wire("IX100", 50), "IX2");
  EXPECT_EQ(wire("NOX-8388608", 1), "NOX-8388608");
  EXPECT_EQ(wire("PHL3000", 1000), "PHL3000");  // PLL values are not scaled
  EXPECT_EQ(wire("LMXN-1", 1000), "LMXN-1");
  EXPECT_EQ(wire("V1=25000", 1000), "V1=25000");
  EXPECT_EQ(wire("URX1000", 1), "URX1000");
  std::string error;
  EXPECT_FALSE(prepare_command("FSX.5", error));
  EXPECT_NE(error.find("internal units"), std::string::npos) << error;
}

TEST(WhedcoCommands, AxisMasksExpandToLetters) {
  EXPECT_EQ(axis_letters(1), "X");
  EXPECT_EQ(axis_letters(15), "XYWZ");
  EXPECT_EQ(axis_letters(12), "WZ");
  EXPECT_FALSE(axis_letters(0));
  EXPECT_FALSE(axis_letters(16));
  EXPECT_EQ(wire("RA[3]", 1), "RAXY");
  EXPECT_EQ(wire("RI[15]", 1), "RIXYWZ");
  EXPECT_EQ(wire("SHZ[4]", 1), "SHZW");
  EXPECT_EQ(wire("LI[8]F", 1), "LIZF");
  EXPECT_EQ(wire("STP[2]100", 1000), "STPY0.1");
  expect_refusals({{"SHZ[3]", "exactly one"},
                   {"RA[0]", "selects no axis"},
                   {"RA[16]", "selects no axis"},
                   {"RA[X]", "holds a number"},
                   {"RA[3", "without ']'"},
                   {"RA3]", "without '['"}});
}

TEST(WhedcoCommands, GatewayNeverSendsWhatTheDigestKeepsOut) {
  for (const char* c : {"CB", "MS", "ML", "DG1", "DE5", "DEL", "ED", "X", "TC20"})
    EXPECT_NE(refusal(c).find("kept out"), std::string::npos) << c;
  expect_refusals({{"AMX1!", "ignore the whole line"},
                   {"4RPX", "adds the unit address"},
                   {"rpx", "upper case"},
                   {"AMX 5", "no spaces"},
                   {"RPX\r", "adds the CR"},
                   {"", "empty"}});
  // Lookalikes that are legitimate: EB, EL, DB, DR, CT, XOR inside a condition.
  for (const char* c : {"EB", "ELX1", "DBX5", "DR10", "CTX8", "IFB1XB2GT3", "CRX"}) {
    std::string error;
    EXPECT_TRUE(prepare_command(c, error)) << c << ": " << error;
  }
}

TEST(WhedcoCommands, QueryKindsAndUnitRatioTracking) {
  std::string error;
  EXPECT_EQ(prepare_command("FC", error)->kind, QueryKind::unit_fault);
  EXPECT_EQ(prepare_command("FCW", error)->kind, QueryKind::axis_fault);
  EXPECT_EQ(prepare_command("RDI", error)->kind, QueryKind::bit_list);
  EXPECT_EQ(prepare_command("RDB", error)->kind, QueryKind::bit_list);
  EXPECT_EQ(prepare_command("RS", error)->kind, QueryKind::status_word);
  EXPECT_EQ(prepare_command("RSY", error)->kind, QueryKind::status_word);
  EXPECT_EQ(prepare_command("RSI3", error)->kind, QueryKind::plain);  // reset I/O 3, no query
  EXPECT_TRUE(prepare_command("RPZ", error)->scaled_reply);
  EXPECT_TRUE(prepare_command("FEX", error)->scaled_reply);
  EXPECT_FALSE(prepare_command("RSX", error)->scaled_reply);
  EXPECT_EQ(prepare_command("RA1", error)->quantity, Quantity::none);  // analog, not a run
  EXPECT_EQ(prepare_command("VOX5", error)->quantity, Quantity::none);
  const auto q = prepare_command("URY?", error);
  EXPECT_EQ(q->unit_ratio_axis, 'Y');
  EXPECT_FALSE(q->unit_ratio_written);
  const auto w = prepare_command("URY250", error);
  EXPECT_EQ(w->unit_ratio_axis, 'Y');
  EXPECT_EQ(w->unit_ratio_written, 250);
  EXPECT_FALSE(prepare_command("URY0", error)->unit_ratio_axis);
}

TEST(WhedcoFraming, PromptEndsTheReply) {
  EXPECT_EQ(frame_length("*", "4HT", EchoMode::non_echo), 1u);
  EXPECT_EQ(frame_length("", "4HT", EchoMode::non_echo), 0u);
  EXPECT_EQ(frame_length("1250\r\n", "4RPX", EchoMode::non_echo), 0u);
  EXPECT_EQ(frame_length("1250\r\n*\r\n", "4RPX", EchoMode::non_echo), 7u);
  EXPECT_EQ(frame_length("\r\n-12.5\r\n\r\n*", "4RPX", EchoMode::automatic), 12u);
}

TEST(WhedcoFraming, EchoIsSkippedBeforeLookingForThePrompt) {
  // A `*` inside the echoed line (a multiplication) is not the prompt.
  const std::string line = "4V3=A1*V1";
  EXPECT_EQ(frame_length("4V3=A1", line, EchoMode::echo), 0u);
  EXPECT_EQ(frame_length("4V3=A1*V1\r\n", line, EchoMode::echo), 0u);
  EXPECT_EQ(frame_length("4V3=A1*V1\r\n*", line, EchoMode::echo), 12u);
  EXPECT_EQ(frame_length("4V3=A1*V1\r\n*", line, EchoMode::automatic), 12u);
  // In non-echo mode nothing is skipped: the echo's star ends the frame (and is then garbled).
  EXPECT_EQ(frame_length("4V3=A1*V1\r\n*", line, EchoMode::non_echo), 7u);
  // Echo without the address character, lower case.
  EXPECT_EQ(frame_length("v3=a1*v1\r*", line, EchoMode::echo), 10u);
  // Auto: "4" could still become the echo; "42" cannot.
  EXPECT_EQ(frame_length("4", "4V1=?", EchoMode::automatic), 0u);
  EXPECT_EQ(frame_length("42\r\n*", "4V1=?", EchoMode::automatic), 5u);
}

TEST(WhedcoFraming, StripEcho) {
  bool echoed = false;
  EXPECT_EQ(strip_echo("4RPX\r\n1250\r\n*", "4RPX", echoed), "1250\r\n*");
  EXPECT_TRUE(echoed);
  EXPECT_EQ(strip_echo(" 1250\r\n*", "4RPX", echoed), "1250\r\n*");
  EXPECT_FALSE(echoed);
}

TEST(WhedcoReplies, NumbersWithSignPointLabelAndSpaces) {
  const auto n = parse_numbers("  -12.5 +3 .25 7", false);
  ASSERT_TRUE(n);
  ASSERT_EQ(n->size(), 4u);
  EXPECT_EQ((*n)[0].mantissa, -125);
  EXPECT_EQ((*n)[0].decimals, 1);
  EXPECT_EQ((*n)[1].mantissa, 3);
  EXPECT_EQ((*n)[2].mantissa, 25);
  EXPECT_EQ((*n)[2].decimals, 2);
  EXPECT_EQ(parse_numbers("V1=25000", false)->front().mantissa, 25000);
  EXPECT_EQ(parse_numbers("X: -7", false)->front().mantissa, -7);
  EXPECT_EQ(parse_numbers("A", true)->front().mantissa, 10);
  EXPECT_EQ(parse_numbers("1F", true)->front().mantissa, 31);
  // Hex as the manual prints it, in upper case: a lower-case letter is a garbled character.
  EXPECT_FALSE(parse_numbers("1f", true));
  EXPECT_FALSE(parse_numbers("v1=25000", false));  // labels as printed, in upper case
  EXPECT_TRUE(parse_numbers("", false)->empty());
  EXPECT_FALSE(parse_numbers("?", false));
  EXPECT_FALSE(parse_numbers("Illegal Command", false));
  EXPECT_FALSE(parse_numbers("12x", false));
  EXPECT_FALSE(parse_numbers("1.2.3", false));
  EXPECT_FALSE(parse_numbers("-", false));
  EXPECT_FALSE(parse_numbers("1234567890123456789", false));
}

TEST(WhedcoReplies, UserUnitsToInternal) {
  EXPECT_EQ(to_internal({-125, 1}, 1000), -12500);
  EXPECT_EQ(to_internal({3333, 4}, 3), 1);  // 0.3333 * 3 = 0.9999 -> 1 pp
  EXPECT_EQ(to_internal({-6667, 4}, 3), -2);
  EXPECT_EQ(to_internal({5, 1}, 1), 1);  // half away from zero
  EXPECT_EQ(to_internal({-5, 1}, 1), -1);
  EXPECT_EQ(to_internal({999999999999999999, 0}, 10000), std::nullopt);
  EXPECT_EQ(user_units(5, 4, Quantity::length), "1.25");
  EXPECT_EQ(user_units(-8388607, 1, Quantity::length), "-8388607");
}

// §6.2: non-echo replies the code (a hex digit), echo the English text.
TEST(WhedcoReplies, AxisFaultTexts) {
  for (int code : {0, 2, 3, 4, 5, 6, 7, 8, 9, 10})
    EXPECT_EQ(axis_fault_from_text(axis_fault_text(code)), code) << code;
  EXPECT_EQ(axis_fault_from_text("EXCESSIVE FOLLOWING ERROR"), 3);
  EXPECT_EQ(axis_fault_from_text("Overtemperature"), 2);
  EXPECT_EQ(axis_fault_from_text("Over current"), 9);
  EXPECT_EQ(axis_fault_from_text("?"), std::nullopt);
}

// §6.1.2: FC in echo mode; the numbers are this family's encoding (base*256 + axis byte).
TEST(WhedcoReplies, UnitFaultTexts) {
  EXPECT_EQ(unit_fault_from_text("Unit Functional"), kUnitFunctional);
  EXPECT_EQ(unit_fault_from_text("Power Failure"), kUnitPowerFailure);
  EXPECT_EQ(unit_fault_from_text("Axis Initialize"), kUnitAxisInitialized);
  EXPECT_EQ(unit_fault_from_text("Axis Initialized"), kUnitAxisInitialized);
  EXPECT_EQ(unit_fault_from_text("Arithmetic Overflow"), kUnitArithmeticOverflow);
  EXPECT_EQ(unit_fault_from_text("X Faulted"), 0x11);
  EXPECT_EQ(unit_fault_from_text("Z Faulted"), 0x88);
  EXPECT_EQ(unit_fault_from_text("Y Not Responding"), 0x02);
  EXPECT_EQ(unit_fault_from_text("Power Failure\r\nW Faulted\r\nX Not Responding"), 0x100 + 0x45);
  EXPECT_EQ(unit_fault_from_text("Gremlins"), std::nullopt);
  EXPECT_EQ(unit_fault_from_text(""), std::nullopt);
}

TEST(WhedcoReplies, BitStringsFromRdiAndRdb) {
  EXPECT_EQ(parse_bit_string("100000000001"), 0x801);
  EXPECT_EQ(parse_bit_string(" 01000000 "), 0x2);
  EXPECT_EQ(parse_bit_string("1001"), std::nullopt);  // short: an ordinary number
  EXPECT_EQ(parse_bit_string("10000002"), std::nullopt);
}

}  // namespace
}  // namespace fieldgate::whedco
