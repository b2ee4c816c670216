// The IMS party-line simulator with injected time: echo rules, query formats, motion, globals,
// faults and the control channel. No PTY, no sleeps.
#include <gtest/gtest.h>

#include "sim/ims/party_line.hpp"

namespace fieldgate::sim::ims {
namespace {

using namespace std::chrono_literals;

const SimTime kT0 = SimTime{} + std::chrono::hours(1000);

SimTime at(double seconds) {
  return kT0 +
         std::chrono::duration_cast<SimClock::duration>(std::chrono::duration<double>(seconds));
}

class Chain : public ::testing::Test {
 protected:
  void SetUp() override { make({}); }

  void make(PartyLineOptions options) {
    if (options.names == std::vector<char>{'A'}) options.names = {'A', 'B', 'C'};
    chain_ = std::make_unique<PartyLine>(
        options, faults_, [this] { return now_; }, kT0);
  }

  // The host sends `line` at time `t`, all at once; returns echo and reply together.
  std::string exchange(std::string_view line, double t = 0) {
    now_ = at(t);
    std::string out = chain_->echo(line);
    std::string pending(line);
    while (const std::size_t n = PartyLine::frame(pending)) {
      out += chain_->respond(pending.substr(0, n), now_).bytes;
      pending.erase(0, n);
    }
    return out;
  }

  std::string control(const std::string& verb, std::vector<std::string> args, double t = 0) {
    return chain_->control(verb, args, at(t)).value_or("(not a family verb)");
  }

  FaultInjection faults_;
  SimTime now_ = kT0;
  std::unique_ptr<PartyLine> chain_;
};

TEST_F(Chain, Framing) {
  EXPECT_EQ(PartyLine::frame("AZ\n"), 3u);
  EXPECT_EQ(PartyLine::frame("AZ"), 0u);
  EXPECT_EQ(PartyLine::frame("AZ\r"), 0u) << "CR is no terminator in party mode";
  EXPECT_EQ(PartyLine::frame("\x1b"
                             "AZ\n"),
            1u);
  EXPECT_EQ(PartyLine::frame("AR-20\x1b"), 5u) << "ESC cuts the line short";
  EXPECT_EQ(PartyLine::frame("\x03"), 1u);
}

TEST_F(Chain, NamedUnitEchoesAndAnswers) {
  EXPECT_EQ(exchange("AZ\n"), "Z\n      0\r\n");
  EXPECT_EQ(exchange("B^\n"), "^\n      0\r\n");
  EXPECT_EQ(exchange("CA129\n"), "A129\n      0\r\n");
  EXPECT_EQ(exchange("AV3000\n"), "V3000\n\r\n");
  EXPECT_DOUBLE_EQ(chain_->unit('A')->parameters().slew, 3000);
  EXPECT_DOUBLE_EQ(Indexer::achievable_rate(3000), 1'228'800.0 / 409);  // 3004.4, digest §5
}

TEST_F(Chain, EchoOptions) {
  PartyLineOptions options;
  options.echo_name = true;
  options.completion = false;
  make(options);
  EXPECT_EQ(exchange("AZ\n"), "AZ\n      0\r\n");
  EXPECT_EQ(exchange("AV3000\n"), "AV3000\n");
}

TEST_F(Chain, UnknownNamesAndStrayCharactersGetSilence) {
  EXPECT_EQ(exchange("DZ\n"), "");
  EXPECT_EQ(exchange("\rAZ\n"), "") << "a CR where a name belongs wakes nobody";
  EXPECT_EQ(exchange("\n"), "");
  control("axis-off", {"B"});
  EXPECT_EQ(exchange("BZ\n"), "");
  control("axis-on", {"B"});
  EXPECT_EQ(exchange("BZ\n"), "Z\n      0\r\n");
}

TEST_F(Chain, CommandsWithoutEchoInPartyMode) {
  EXPECT_EQ(exchange("AX\n"), "\"32.\r\n");
  EXPECT_EQ(exchange("AP0\n"), "");
  EXPECT_EQ(exchange("AQ 100\n"), "");
  EXPECT_EQ(exchange("Aq\n"), "");
}

TEST_F(Chain, BadLinesAreEchoedButNotExecuted) {
  EXPECT_EQ(exchange("AV30,00\n"), "V30,00\n");
  EXPECT_EQ(exchange("AV1 2 3\n"), "V1 2 3\n");
  EXPECT_EQ(exchange("AR-8388607.991\n"), "R-8388607.991\n") << "more than 12 characters";
  EXPECT_EQ(exchange("A~\n"), "~\n");
  EXPECT_DOUBLE_EQ(chain_->unit('A')->parameters().slew, 2048);
}

TEST_F(Chain, QueryFormats) {
  control("position", {"A", "-2500"});
  EXPECT_EQ(exchange("AZ\n"), "Z\n  -2500\r\n");
  EXPECT_EQ(exchange("Az\n"), "z\n  -2500\r\n");
  EXPECT_EQ(exchange("A]0\n"), "]0\n      0\r\n");
  control("limit", {"A", "both"});
  EXPECT_EQ(exchange("A]0\n"), "]0\n      3\r\n");
  EXPECT_EQ(exchange("A]1\n"), "]1\n      1\r\n")
      << "at -2500 the home switch (edge -1000) is high";
  control("inputs", {"A", "5"});
  exchange("AA48\n");
  EXPECT_EQ(exchange("AA129\n"), "A129\n     53\r\n");  // IN1, IN3, OUT2, OUT3
  // Variable resolution: full steps with two decimals.
  exchange("AH1\n");
  chain_->unit('A')->set_position(kT0, 12.5);
  EXPECT_EQ(exchange("AZ\n"), "Z\n  12.50\r\n");
}

TEST_F(Chain, NvmReadsTheSavedParameterBlock) {
  exchange("AK 22 45\n");
  exchange("AS\n");
  EXPECT_EQ(chain_->unit('A')->eeprom_writes(), 1);
  EXPECT_EQ(exchange("A[1990 2\n"), "[1990 2\n22 45\r\n");
  EXPECT_EQ(exchange("A[2019 1\n"), "[2019 1\n65\r\n") << "the name";
  const std::string twelve = exchange("A[1984 12\n");
  EXPECT_EQ(std::count(twelve.begin(), twelve.end(), '\n'), 3) << twelve;
}

TEST_F(Chain, AbsoluteAndRelativeIndexes) {
  exchange("AV2000\n");
  exchange("AK0 0\n");
  exchange("AR1000\n", 0);
  EXPECT_EQ(chain_->unit('A')->status(at(0.1)) & 1, 1);
  EXPECT_NEAR(chain_->unit('A')->position(at(0.25)), 500, 1);  // V2000 runs at 2001.3
  EXPECT_EQ(exchange("A^\n", 0.6), "^\n      0\r\n");
  EXPECT_EQ(exchange("AZ\n", 0.6), "Z\n   1000\r\n");
  exchange("A+500\n", 1);
  exchange("A-200.5\n", 2);
  EXPECT_EQ(exchange("AZ\n", 3), "Z\n   1300\r\n");  // 1299.5, shown whole in FR mode
  EXPECT_EQ(exchange("BZ\n", 3), "Z\n      0\r\n");
}

TEST_F(Chain, SecondIndexQueuesAndCompletesLate) {
  exchange("AV1000\n");
  exchange("AK0 0\n");
  exchange("AR1000\n", 0);  // one second
  now_ = at(0.2);
  EXPECT_EQ(chain_->echo("AR0\n"), "R0\n");
  const DeviceReply reply = chain_->respond("AR0\n", at(0.2));
  EXPECT_EQ(reply.bytes, "\r\n");
  EXPECT_NEAR(std::chrono::duration<double>(reply.extra_delay).count(), 0.8, 0.01);
  EXPECT_NEAR(chain_->unit('A')->position(at(1.5)), 500, 1);
  EXPECT_DOUBLE_EQ(chain_->unit('A')->position(at(2.5)), 0);
}

TEST_F(Chain, WaitHoldsItsLineFeed) {
  exchange("AV1000\n");
  exchange("AK0 0\n");
  exchange("AR500\n", 0);
  now_ = at(0.1);
  EXPECT_EQ(chain_->echo("AW0\n"), "W0");
  const DeviceReply reply = chain_->respond("AW0\n", at(0.1));
  EXPECT_EQ(reply.bytes, "\n\r\n");
  EXPECT_NEAR(std::chrono::duration<double>(reply.extra_delay).count(), 0.4, 0.01);
}

TEST_F(Chain, VelocityMode) {
  exchange("AK 4 4\n");  // 2000 steps/s²
  exchange("AM+2000\n", 0);
  EXPECT_EQ(chain_->unit('A')->status(at(0.5)), 1 | 32);
  EXPECT_EQ(chain_->unit('A')->status(at(2)), 1 | 2);
  EXPECT_DOUBLE_EQ(chain_->unit('A')->step_rate(at(2)), 2000);
  exchange("AM0\n", 2);
  EXPECT_EQ(chain_->unit('A')->status(at(4)), 0);
  exchange("AM-5\n", 5);  // below the minimum speed of 20
  EXPECT_DOUBLE_EQ(chain_->unit('A')->step_rate(at(6)), 20);
}

TEST_F(Chain, HomeFromEitherSideOfTheSwitchWithoutZeroing) {
  exchange("AK0 0\n");
  exchange("AI 100\n");
  exchange("AF1000 0\n", 0);  // low switch, dir 0: search - towards the edge at -1000
  EXPECT_EQ(chain_->unit('A')->status(at(0.5)), 1 | 8);
  EXPECT_EQ(exchange("A^\n", 1.5), "^\n      0\r\n");
  EXPECT_EQ(exchange("AZ\n", 1.5), "Z\n  -1000\r\n");
  exchange("AO\n", 2);
  EXPECT_EQ(exchange("AZ\n", 2), "Z\n      0\r\n");
  // High side (physical -2000): dir 0 goes +, leaves the switch, creeps back at I.
  control("position", {"B", "-2000"});
  exchange("BK0 0\n");
  exchange("BI 100\n");
  exchange("BF1000 0\n", 0);
  EXPECT_EQ(chain_->unit('B')->status(at(1.5)) & 8, 8);
  EXPECT_EQ(exchange("BZ\n", 1.5), "Z\n   -999\r\n");
  EXPECT_EQ(exchange("B^\n", 1.6), "^\n      0\r\n");
  EXPECT_EQ(exchange("BZ\n", 1.6), "Z\n  -1000\r\n");
}

TEST_F(Chain, OriginIsRefusedWhileMoving) {
  exchange("AK0 0\n");
  exchange("AM1000\n", 0);
  exchange("AO\n", 1);
  EXPECT_GT(chain_->unit('A')->position(at(1)), 900);
}

TEST_F(Chain, LimitsStopMotionInTheirDirection) {
  exchange("AK0 0\n");
  control("limit", {"A", "plus"});
  exchange("AR1000\n", 0);
  EXPECT_EQ(chain_->unit('A')->status(at(0.1)), 0);
  exchange("AR-100\n", 0.2);
  EXPECT_DOUBLE_EQ(chain_->unit('A')->position(at(2)), -100);
  control("limit", {"A", "none"});
  exchange("AM1000\n", 2);
  control("limit", {"A", "plus"}, 3);
  EXPECT_EQ(chain_->unit('A')->status(at(3.1)), 0);
}

TEST_F(Chain, GlobalCharactersReachEveryUnit) {
  for (const char* name : {"A", "B", "C"}) exchange(std::string(name) + "M1000\n", 0);
  EXPECT_EQ(exchange("@\n", 1), "") << "nobody answers a global soft stop";
  for (char name : {'A', 'B', 'C'}) EXPECT_EQ(chain_->unit(name)->status(at(3)), 0) << name;

  for (const char* name : {"A", "B"}) exchange(std::string(name) + "M1000\n", 4);
  const double before = chain_->unit('A')->position(at(5));
  EXPECT_EQ(exchange("\x1b", 5), "");
  EXPECT_EQ(chain_->unit('A')->status(at(5)), 0) << "ESC stops at once";
  EXPECT_DOUBLE_EQ(chain_->unit('A')->position(at(6)), before);

  exchange("AV5000\n", 6);
  exchange("AS\n", 6);
  exchange("AV7000\n", 6);
  EXPECT_EQ(exchange("\x03", 7), "");
  EXPECT_DOUBLE_EQ(chain_->unit('A')->position(at(7)), 0);
  EXPECT_DOUBLE_EQ(chain_->unit('A')->parameters().slew, 5000) << "saved parameters reload";
}

TEST_F(Chain, EscapeAbandonsAHalfLine) {
  EXPECT_EQ(exchange("AV30\x1b"), "V30");
  EXPECT_DOUBLE_EQ(chain_->unit('A')->parameters().slew, 2048);
  EXPECT_EQ(exchange("AZ\n"), "Z\n      0\r\n");
}

TEST_F(Chain, GlobalAddressCollides) {
  const std::string out = exchange("*M0\n");
  ASSERT_FALSE(out.empty());
  EXPECT_NE(out.substr(0, 2), "M0") << "three units echo at once";
  PartyLineOptions one;
  one.names = {'Q'};
  make(one);
  EXPECT_EQ(exchange("*M0\n"), "M0\n\r\n") << "a single unit answers cleanly";
}

TEST_F(Chain, DuplicateNameGarblesEverything) {
  control("duplicate", {"B", "on"});
  const std::string out = exchange("BZ\n");
  ASSERT_EQ(out.size(), std::string("Z\n      0\r\n").size());
  for (char c : out) {
    if (c != '\n') {
      EXPECT_TRUE(static_cast<unsigned char>(c) & 0x80);
    }
  }
  control("duplicate", {"B", "off"});
  EXPECT_EQ(exchange("BZ\n"), "Z\n      0\r\n");
}

TEST_F(Chain, InjectedGarbageAndTruncationHitTheEcho) {
  faults_.garbage_replies = 1;
  EXPECT_EQ(exchange("DZ\n"), "") << "silence does not use up the fault";
  std::string out = exchange("AZ\n");
  EXPECT_EQ(faults_.garbage_replies, 0u);
  ASSERT_GE(out.size(), 2u);
  EXPECT_NE(out.substr(0, 2), "Z\n");
  EXPECT_EQ(out[1], '\n') << "the line feed survives, so the host sees a complete bad echo";
  faults_.truncated_replies = 1;
  EXPECT_EQ(exchange("AV3000\n"), "V");
  EXPECT_DOUBLE_EQ(chain_->unit('A')->parameters().slew, 3000) << "the unit still took it";
  EXPECT_EQ(exchange("AZ\n"), "Z\n      0\r\n");
}

TEST_F(Chain, FastUnitOverrunsOnBackToBackCharacters) {
  exchange("AK0 0\n");
  exchange("AM15000\n", 0);
  now_ = at(1);
  EXPECT_EQ(chain_->echo("AZ\n"), "Z");
  EXPECT_TRUE(chain_->respond("AZ\n", at(1)).bytes.empty());
  // One character at a time (paced by the echo) gets through.
  std::string out;
  for (char c : std::string("AZ\n")) out += chain_->echo(std::string(1, c));
  out += chain_->respond("AZ\n", at(1)).bytes;
  EXPECT_EQ(out, "Z\n  15000\r\n");
  // Another, slow unit is not affected.
  EXPECT_EQ(exchange("BZ\n", 1), "Z\n      0\r\n");
  PartyLineOptions never;
  never.overrun_above = 0;
  make(never);
  exchange("AK0 0\n");
  exchange("AM15000\n", 0);
  EXPECT_EQ(exchange("AZ\n", 1), "Z\n  15000\r\n");
}

// A read does not say when its characters came. A line paced by time that the simulator read
// late (a loaded machine) arrives in pieces that are each long enough after the one before;
// the same characters close together are back to back.
TEST_F(Chain, ALateReadOfAPacedLineIsNotAnOverrun) {
  exchange("AK0 0\n");
  exchange("AM15000\n", 0);
  now_ = at(1);
  std::string out = chain_->echo("A");
  now_ += std::chrono::milliseconds(12);  // '^', '\n' sent 5 ms apart, read together
  out += chain_->echo("^\n");
  EXPECT_EQ(out, "^\n");
  EXPECT_FALSE(chain_->respond("A^\n", now_).bytes.empty());
  EXPECT_NE(control("status", {"A"}, 1).find("overruns=0"), std::string::npos);

  now_ = at(2);
  out = chain_->echo("A");
  now_ += std::chrono::microseconds(300);  // too soon for two characters a spacing apart
  out += chain_->echo("^\n");
  EXPECT_EQ(out, "^") << "the unit lost the rest of the line";
  EXPECT_TRUE(chain_->respond("A^\n", now_).bytes.empty());
  EXPECT_NE(control("status", {"A"}, 2).find("overruns=1"), std::string::npos);
}

TEST_F(Chain, ControlChannel) {
  EXPECT_EQ(control("axis-off", {"A"}), "ok axis-off A");
  EXPECT_FALSE(chain_->online('A'));
  EXPECT_EQ(control("axis-off", {"E"}), "error: no unit named 'E'");
  EXPECT_EQ(control("duplicate", {"B", "maybe"}), "error: usage: duplicate NAME on|off");
  EXPECT_EQ(control("position", {"B", "x"}), "error: usage: position NAME VALUE");
  EXPECT_EQ(control("limit", {"B", "up"}), "error: usage: limit NAME plus|minus|both|none");
  EXPECT_EQ(control("status", {"C"}).rfind("ok C position=0.00 status=0", 0), 0u);
  EXPECT_EQ(control("reset", {}), "ok reset");
  EXPECT_EQ(control("bogus", {}), "(not a family verb)");
  EXPECT_NE(PartyLine::control_help().find("duplicate NAME on|off"), std::string::npos);
}

TEST(ImsNames, CommandLineList) {
  EXPECT_EQ(parse_names("A,B,c"), (std::vector<char>{'A', 'B', 'c'}));
  EXPECT_THROW(parse_names("A,A"), std::invalid_argument);
  EXPECT_THROW(parse_names("A,@"), std::invalid_argument);
  EXPECT_THROW(parse_names("AB"), std::invalid_argument);
  EXPECT_THROW(parse_names(""), std::invalid_argument);
}

// The party line behind the common line loop, with wire emulation at 9600 baud.
TEST(ImsLineExchange, EchoLeavesAsCharactersArriveAndTheResultAfterTheTurnaround) {
  FaultInjection faults;
  SimTime now = kT0;
  PartyLineOptions options;
  options.names = {'A'};
  PartyLine chain(
      options, faults, [&] { return now; }, kT0);
  LineDeviceOptions line;
  line.wire = {true, WireTiming(9600), 1000us};
  LineExchange exchange(chain.hooks(), line, faults);
  exchange.receive(kT0, "AZ\n");
  std::string out;
  while (const auto due = exchange.next_deadline()) {
    now = *due;
    exchange.advance(*due, out);
  }
  EXPECT_EQ(out, "Z\n      0\r\n");
  EXPECT_GE(now - kT0, WireTiming(9600).wire_time(3) + 1000us + WireTiming(9600).wire_time(9));
}

}  // namespace
}  // namespace fieldgate::sim::ims
