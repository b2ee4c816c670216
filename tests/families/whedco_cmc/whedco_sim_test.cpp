// The Whedco CMC simulator's device logic with injected time: grammar, parameters and user
// units, motion, profiles, faults, and the line with several units.
#include <gtest/gtest.h>

#include <sstream>

#include "sim/whedco/cmc_line.hpp"
#include "tests/harness/exchange_table.hpp"
#include "tests/harness/random_text.hpp"

namespace fieldgate::sim::whedco {
namespace {

using fieldgate::test::Exchange;
using fieldgate::test::expect_replies;

const SimTime kT0 = SimTime{} + std::chrono::hours(1000);

SimTime at(double seconds) {
  return kT0 +
         std::chrono::duration_cast<SimClock::duration>(std::chrono::duration<double>(seconds));
}

UnitOptions options(std::string axes = "WXYZ", bool echo = true) {
  UnitOptions o;
  o.address = 4;
  o.axes = std::move(axes);
  o.echo = echo;
  return o;
}

struct Bench {
  explicit Bench(UnitOptions o = options()) : unit(std::move(o), kT0) {}
  std::string send(std::string_view body, double seconds = 0) {
    return unit.execute(body, at(seconds));
  }
  CmcUnit unit;
};

TEST(WhedcoGrammar, EveryTranscriptLineParses) {
  // The host lines of digest §10 (without address), OCR fixed as the digest lists.
  const char* lines =
      "DE1 FSX.5 LIXF LMXN-1 SBZX ED GT1 ACX20 VX5 IMX10 RIX ACY20 ACW20 ACZ20 VX2 VW4 STZX STZY "
      "STZW STZZ AMX5 AMY5 AMW10 AMZ10 RAXYWZ RX2 CRX ELX.5 ELY1 IMY2 RRX RX-2 IMX-2 IMY-2 VX3 VW3 "
      "RW0 IMZ4 RRA VX1 RX1 IMX1 IMX-1 IMX-4 RIY FSX5 LMXN1 AEX1 FSX1 LMXA1 FSY1 LIYF LMYA2 AEY1 "
      "LIXE1 LMXN.9 V1=25000 V2=2047 V3=A1*V1 V3=V3/V2 V4=A2*V1 V4=V4/V2 RXV3 VXV4 RM9 V1=10 "
      "V2=50 V3=T1*V1 V3=V3+T2 V3=V3*V1 V3=V3+T3 V3=V3+T4 V3=V3*V2 GS14 AMXV3 RAX LMXV0 PHG260 "
      "PHZ245 PHL3000 FSX.1 UE0 WTI AEX0 SPH PHO0 V0=51 UE1 PTA01BX10 PTA01EX11 PTA02BX11 "
      "PTA02EX10 PTA01EX10.1 PTA01BY10 PTA01EY10.1 SPAXAYA TMX TMY RAXY WTMA WTT5 AMX0 AMY0 GT19 "
      "TC20 GT20 IFI9AB3GT5 IFV1>V3GS6 WTENI2ANI3 WTENI5 WTEI5 V1=A1+A2 VOX5 VOX0 VOW0 X DEL "
      "AMX? VX? URX? V1=? RS RSX RCX RPX FEX FC FCX RA1 RDB RDI STI1 RSI1 STB2 RSBA DR10 WB HT EB "
      "ITX URX1000 NOX-8388608 POX8388607 WRX1 GNX260 DFX1 AD1100 AO2V3 IFIAAB3GT5";
  std::istringstream in(lines);
  for (std::string w; in >> w;) EXPECT_TRUE(parse_command(w)) << w;
}

TEST(WhedcoGrammar, RefusesWhatTheManualForbids) {
  for (const char* bad :
       {"VC=10*T1", "AMQ5", "RA", "RAXX", "AEX2", "LMXN101", "DE", "GT", "V1=PX*", "WTT700", "IFB1",
        "PTA51BX1", "amx5", "AMX 5", "V1=99999999999", "LIXE4", "RSX1", "Q"})
    EXPECT_FALSE(parse_command(bad)) << bad;
  EXPECT_TRUE(allowed_in_profile(*parse_command("AMX5")));
  for (const char* not_in_profile : {"WB", "ITX", "URX2", "RPX", "AMX?", "V1=?", "RA1", "DR10"})
    EXPECT_FALSE(allowed_in_profile(*parse_command(not_in_profile))) << not_in_profile;
}

TEST(WhedcoUnit, ParametersAreUserUnitsStoredAsPulses) {
  Bench b;
  const std::vector<Exchange> transcript = {
      {"URX1000", ""},
      {"URX?", "1000"},
      {"AMX12.5", ""},
      {"AMX?", "12.5"},
      {"URX500", ""},
      {"AMX?", "25", "internal 12500 pp stay, the user value follows UR"},
      {"ACX?", "160", "default 80000 pp/s2"},
      {"V3=-7", ""},
      {"AMXV3", ""},
      {"AMX?", "-0.014", "a variable loads internal units"},
      {"VX?", "0"},
      {"VX5", ""},
      {"VX?", "5"},
      {"URX0", "?"},
      {"ACX1", "?", "below 80000 pp/s2"},
      {"FSX0.1", "?", "50 pp/s is below the 200 pp/s minimum"},
      {"AMX99999", "?", "beyond the 24-bit register"},
      {"RPQ", "?"},
      {"AMX5!", "", "a '!' makes the unit ignore the line"},
      {"AMX?", "-0.014"},
  };
  expect_replies(b, transcript);
}

TEST(WhedcoUnit, AbsentAxisIsRefused) {
  Bench b(options("XY"));
  EXPECT_EQ(b.send("RPW"), "?");
  EXPECT_EQ(b.send("AMW5"), "?");
  EXPECT_EQ(b.send("RAXW"), "?");
  EXPECT_EQ(b.send("RPX"), "0");
}

TEST(WhedcoUnit, InterpolatedMoveArrivesTogether) {
  Bench b;
  b.send("ACX100000");
  b.send("ACY100000");
  b.send("VX1000");
  b.send("AMX1000");
  b.send("AMY500");
  EXPECT_EQ(b.send("RAXY"), "");
  EXPECT_EQ(b.unit.unit_status(at(0.5)) & status::busy, status::busy);
  EXPECT_EQ(b.unit.axis_status('X', at(0.5)) & status::busy, status::busy);
  const double x = std::stod(b.send("RCX", 0.5));
  const double y = std::stod(b.send("RCY", 0.5));
  EXPECT_GT(x, 0);
  EXPECT_NEAR(y, x / 2, 1.0) << "straight line";
  EXPECT_EQ(b.send("RCX", 3), "1000");
  EXPECT_EQ(b.send("RCY", 3), "500");
  EXPECT_EQ(b.send("RPX", 3), "1000");
  EXPECT_EQ(b.send("FEX", 3), "0");
  EXPECT_EQ(b.unit.unit_status(at(3)) & status::busy, 0);
  // Incremental, from where the axis is.
  b.send("IMX-250", 3);
  b.send("RIX", 3);
  EXPECT_EQ(b.send("RCX", 10), "750");
}

TEST(WhedcoUnit, ServoFollowingErrorWhileMoving) {
  Bench b;
  b.send("VX10000");
  b.send("AMX100000");
  b.send("RAX");
  const double fe = std::stod(b.send("FEX", 2.0));
  EXPECT_GT(fe, 5) << "2 ms of lag at speed";
  UnitOptions o = options();
  o.steppers = "X";
  Bench s(o);
  s.send("VX10000");
  s.send("AMX100000");
  s.send("RAX");
  EXPECT_EQ(s.send("FEX", 2.0), "0");
}

TEST(WhedcoUnit, JogAndHalt) {
  Bench b;
  b.send("FSX1000");
  b.send("LIXF");
  b.send("LMXN-1");
  b.send("AEX1");
  EXPECT_NE(b.unit.axis_status('X', at(1)) & status::aux_enabled, 0);
  EXPECT_LT(std::stod(b.send("RCX", 2)), -1000);
  b.send("HT", 2);
  const std::string stopped = b.send("RCX", 3);
  EXPECT_EQ(b.send("RCX", 4), stopped);
  EXPECT_EQ(b.unit.axis_status('X', at(4)), 0);
  // AEX0 decelerates the same way.
  b.send("LMXN1", 4);
  b.send("AEX1", 4);
  b.send("AEX0", 5);
  EXPECT_EQ(b.unit.unit_status(at(6)) & status::busy, 0);
}

TEST(WhedcoUnit, HomeSearchSetsThePosition) {
  Bench b;
  ASSERT_TRUE(b.unit.set_home('Y', 3000));
  b.send("FSY2000");
  b.send("LIYF");
  b.send("LMYN1");
  EXPECT_EQ(b.send("SHPY10"), "");
  EXPECT_NE(b.unit.axis_status('Y', at(0.5)) & status::homing, 0);
  EXPECT_EQ(b.send("STZY", 0.5), "") << "ignored while the axis moves";
  EXPECT_EQ(b.send("RCY", 5), "10");
  const int s = b.unit.axis_status('Y', at(5));
  EXPECT_EQ(s & (status::busy | status::homing), 0);
  EXPECT_NE(s & status::home_input, 0);
  EXPECT_EQ(b.send("STPY-4", 5), "");
  EXPECT_EQ(b.send("RCY", 5), "-4");
  EXPECT_EQ(b.unit.axis_status('Y', at(5)) & status::home_input, status::home_input);
}

TEST(WhedcoUnit, FaultsInEchoAndNonEchoFormat) {
  Bench b;
  EXPECT_EQ(b.send("FC"), "Unit Functional");
  EXPECT_EQ(b.send("FCX"), "Unit Functional");
  b.send("VX1000");
  b.send("AMX100000");
  b.send("RAX");
  ASSERT_TRUE(b.unit.inject_fault('X', 3, at(1)));
  EXPECT_EQ(b.send("FC", 1), "X Faulted");
  EXPECT_EQ(b.send("FCX", 1), "Excessive Following Error");
  const std::string frozen = b.send("RCX", 1);
  EXPECT_EQ(b.send("RCX", 2), frozen) << "a faulted axis stops dead";
  b.unit.set_echo(false);
  EXPECT_EQ(b.send("FC", 2), "17");
  EXPECT_EQ(b.send("FCX", 2), "3");
  EXPECT_NE(b.unit.unit_status(at(2)) & status::faulted, 0);
  EXPECT_EQ(b.send("WB", 3), "");
  EXPECT_EQ(b.send("FC", 3), "0");
  EXPECT_EQ(b.send("FCX", 3), "8");
  ASSERT_TRUE(b.unit.inject_fault('Z', 10, at(3)));
  EXPECT_EQ(b.send("FCZ", 3), "A");
  EXPECT_FALSE(b.unit.inject_fault('Z', 1, at(3))) << "code 1 is not in the manual";
}

TEST(WhedcoUnit, AxisInitializeAndArithmeticOverflowFaultTheCmc0) {
  Bench b;
  b.send("ITX");
  EXPECT_EQ(b.send("FC"), "Axis Initialize");
  b.send("WB");
  b.send("V1=5");
  b.send("V2=V1/V3");
  EXPECT_EQ(b.send("FC"), "Arithmetic Overflow");
  b.unit.set_echo(false);
  EXPECT_EQ(b.send("FC"), "768");
  b.unit.power_cycle(at(1));
  EXPECT_EQ(b.send("FC", 1), "511") << "Power Failure, and every axis reports its own (code 0)";
  EXPECT_EQ(b.send("FCX", 1), "0");
}

TEST(WhedcoUnit, VariablesExpressionsAndIo) {
  Bench b;
  ASSERT_TRUE(b.unit.set_analog(1, 1024));
  b.send("V1=25000");
  b.send("V2=2047");
  b.send("V3=A1*V1");
  b.send("V3=V3/V2");
  EXPECT_EQ(b.send("V3=?"), "12506");
  EXPECT_EQ(b.send("RA1"), "1024");
  b.unit.set_inputs(0x801);
  EXPECT_EQ(b.send("RDI"), "2049");
  b.send("DR20");
  b.send("STI2");
  EXPECT_EQ(b.send("RDI"), "2051");
  b.send("STBA");
  EXPECT_EQ(b.send("RDB"), "1024");
  b.send("V5=PX");
  EXPECT_EQ(b.send("V5=?"), "0");
}

TEST(WhedcoUnit, ProfileDefinitionEditingAndExecution) {
  Bench b;
  // §5.6.1 example profile 2, address stripped.
  for (const char* line : {"DE2", "ACX100000", "VX500", "IMX1000", "RIX", "WTMX", "V9=1", "ED"})
    EXPECT_EQ(b.send(line), "") << line;
  const std::vector<Exchange> transcript = {
      {"RCX", "0", "defined, not run"},
      {"V9=?", "0"},
      {"RPX", "0"},
      {"DE2", "ACX100000", "an existing profile opens in edit mode (§5.17)"},
      {"X", "VX500"},
      {"DEL", ""},
      {"VX1000", ""},
      {"RPX", "?", "queries are not profile statements"},
      {"ED", ""},
  };
  expect_replies(b, transcript);
  EXPECT_NE(b.unit.unit_status(at(0)) & status::defining, status::defining);
  EXPECT_EQ(b.send("GT2", 1), "");
  EXPECT_NE(b.unit.unit_status(at(1.1)) & status::profile_running, 0);
  EXPECT_EQ(b.send("V9=?", 1.1), "0");
  EXPECT_EQ(b.send("V9=?", 10), "1");
  EXPECT_EQ(b.send("RCX", 10), "1000");
  EXPECT_EQ(b.unit.unit_status(at(10)) & status::busy, 0);
  EXPECT_EQ(b.send("GT3"), "?") << "no profile 3";
}

TEST(WhedcoUnit, ProfileRepeatsGosubsAndWaits) {
  Bench b;
  std::string error;
  ASSERT_TRUE(b.unit.define_profile(6, {"V2=V2+V1"}, error));
  ASSERT_TRUE(b.unit.define_profile(5, {"V1=1", "GS6", "WTT0.5", "RM9"}, error)) << error;
  b.send("GT5");
  EXPECT_EQ(b.send("V2=?", 2.2), "5");
  EXPECT_EQ(b.send("V2=?", 20), "10") << "RM9: ten passes";
  EXPECT_FALSE(b.unit.profile_running());
  ASSERT_TRUE(b.unit.define_profile(7, {"WTEI1", "V4=1"}, error));
  b.send("GT7", 20);
  EXPECT_EQ(b.send("V4=?", 21), "0");
  b.unit.set_inputs(1);
  EXPECT_EQ(b.send("V4=?", 22), "1");
  EXPECT_FALSE(b.unit.define_profile(8, {"RPX"}, error));
  ASSERT_TRUE(b.unit.define_profile(9, {"V1=V1+V1", "GT9"}, error));
  b.send("V1=1", 30);
  b.send("GT9", 30);
  EXPECT_EQ(b.unit.unit_fault(), UnitFault::arithmetic_overflow)
      << "an endless loop ends in overflow";
}

TEST(WhedcoUnit, HaltStopsAProfile) {
  Bench b;
  std::string error;
  ASSERT_TRUE(b.unit.define_profile(1, {"AMX100000", "RAX", "WTMA", "V9=1"}, error));
  b.send("GT1");
  b.send("HT", 1);
  EXPECT_FALSE(b.unit.profile_running());
  EXPECT_EQ(b.send("V9=?", 60), "0");
}

TEST(WhedcoLine, OnlyTheAddressedUnitAnswersAndEchoes) {
  LineOptions o;
  o.units = parse_units("4,5", "4:XY,5:WXYZ", "5", "");
  CmcLine line(o, kT0);
  EXPECT_EQ(line.echo("4RPX\r"), "4RPX\r\n");
  EXPECT_EQ(line.handle("4RPX\r", kT0).bytes, "0\r\n*");
  EXPECT_EQ(line.echo("5RP"), "");
  EXPECT_EQ(line.echo("W\r"), "");
  EXPECT_EQ(line.handle("5RPW\r", kT0).bytes, "0\r\n*");
  EXPECT_EQ(line.echo("6RS\r"), "");
  EXPECT_TRUE(line.handle("6RS\r", kT0).bytes.empty());
  EXPECT_TRUE(line.handle("!\r", kT0).bytes.empty()) << "no address: nobody answers";
  EXPECT_EQ(line.handle("4HT\r", kT0).bytes, "*");
  EXPECT_EQ(line.handle("\n4HT\r", kT0).bytes, "*");
  // Echo split over reads.
  EXPECT_EQ(line.echo("4"), "4");
  EXPECT_EQ(line.echo("R"), "R");
  EXPECT_EQ(line.echo("S\r"), "S\r\n");
}

TEST(WhedcoLine, ControlVerbs) {
  LineOptions o;
  o.units = parse_units("4,5", "XY", "", "");
  o.style = ReplyStyle::terminal;
  CmcLine line(o, kT0);
  const auto control = [&](std::string text) {
    std::istringstream in(text);
    std::vector<std::string> words;
    for (std::string w; in >> w;) words.push_back(w);
    return line.control(words[0], std::span(words).subspan(1), kT0).value_or("unknown");
  };
  EXPECT_EQ(control("unit-off 5"), "ok unit-off 5");
  EXPECT_TRUE(line.handle("5RS\r", kT0).bytes.empty());
  EXPECT_EQ(control("unit-on 5"), "ok unit-on 5");
  EXPECT_EQ(line.handle("5RS\r", kT0).bytes, "\r\n 0\r\n*");
  EXPECT_EQ(control("fault 4 y 3"), "ok fault 4 Y 3");
  EXPECT_EQ(line.handle("4FCY\r", kT0).bytes, "\r\n Excessive Following Error\r\n*");
  EXPECT_EQ(control("fault 4 Y A"), "ok fault 4 Y A");
  EXPECT_EQ(control("echo 4 off"), "ok echo 4 off");
  EXPECT_EQ(line.handle("4FCY\r", kT0).bytes, "\r\n A\r\n*");
  EXPECT_EQ(line.echo("4FCY\r"), "");
  EXPECT_EQ(control("fault 4 W 3").substr(0, 6), "error:") << "unit 4 has no W axis";
  EXPECT_EQ(control("fault 9 X 3").substr(0, 6), "error:");
  EXPECT_EQ(control("inputs 4 0x801"), "ok inputs 4 0x801");
  EXPECT_EQ(control("analog 4 2 -100"), "ok analog 4 2 -100");
  EXPECT_EQ(line.handle("4RA2\r", kT0).bytes, "\r\n-100\r\n*");
  EXPECT_EQ(control("home 4 X 500"), "ok home 4 X 500");
  EXPECT_EQ(control("profile 4 3 AMX10;RAX;WTMA;V9=1"), "ok profile 4 3 4 lines");
  EXPECT_EQ(control("profile 4 3 RPX").substr(0, 6), "error:");
  EXPECT_EQ(control("position 4 X"), "ok position 4 X 0");
  EXPECT_EQ(control("power-cycle 5"), "ok power-cycle 5");
  EXPECT_EQ(line.handle("5FC\r", kT0).bytes, "\r\n Power Failure\r\nX Faulted\r\nY Faulted\r\n*");
  EXPECT_EQ(line.handle("5WB\r", kT0).bytes, "\r\n*");
  EXPECT_EQ(line.handle("5FC\r", kT0).bytes, "\r\n Unit Functional\r\n*");
  EXPECT_EQ(control("nonsense"), "unknown");
}

TEST(WhedcoLine, UnitListsFromTheCommandLine) {
  const auto u = parse_units("4,5,0", "WXYZ,5:X", "0", "4:Z");
  ASSERT_EQ(u.size(), 3u);
  EXPECT_EQ(u[0].axes, "WXYZ");
  EXPECT_EQ(u[1].axes, "X");
  EXPECT_EQ(u[0].steppers, "Z");
  EXPECT_TRUE(u[0].echo);
  EXPECT_FALSE(u[2].echo);
  EXPECT_THROW(parse_units("8", "", "", ""), std::invalid_argument);
  EXPECT_THROW(parse_units("4,4", "", "", ""), std::invalid_argument);
  EXPECT_THROW(parse_units("4", "", "5", ""), std::invalid_argument);
}

}  // namespace
}  // namespace fieldgate::sim::whedco

namespace fieldgate::sim::whedco {
namespace {

// Lines made of the grammar's own characters: every one gets an answer, nothing crashes, and
// a profile stuck in a loop cannot hang the simulator.
TEST(WhedcoRobustness, RandomLinesAreAnsweredOrRefused) {
  test::RandomText text(11, "WXYZABCDEFGHILMNOPRSTUV0123456789=?*/+-.<>![]", 1, 12);
  LineOptions o;
  o.units = parse_units("4", "XY", "", "");
  CmcLine line(o, kT0);
  std::string error;
  line.unit(4)->define_profile(1, {"V1=V1+V2", "GT1"}, error);
  for (int i = 0; i < 20000; ++i) {
    const std::string body = text.next();
    const auto reply = line.handle("4" + body + "\r", at(i * 0.001));
    ASSERT_FALSE(reply.bytes.empty()) << body;
    EXPECT_EQ(reply.bytes.back(), '*') << body;
  }
}

}  // namespace
}  // namespace fieldgate::sim::whedco
