// The simulated controller with injected time (no PTY, no sleeps): the manual's transcripts
// (digest §11), handshake timing of capital and lower-case commands, error characters, STOP and
// RESET, homing without mechanics, program memory, wire timing.
#include <gtest/gtest.h>

#include "sim/techno/controller.hpp"
#include "sim/techno/exchange.hpp"

namespace fieldgate::sim::techno {
namespace {

using namespace std::chrono_literals;

class Rig {
 public:
  explicit Rig(ControllerOptions options = {}, ExchangeOptions exchange = {})
      : controller_(options, t0_), exchange_(controller_, exchange, faults_) {}

  SimTime at(double seconds) const {
    return t0_ +
           std::chrono::duration_cast<SimClock::duration>(std::chrono::duration<double>(seconds));
  }
  // Sends bytes at `seconds` and returns what the controller has sent by then.
  std::string send(double seconds, std::string_view bytes) {
    exchange_.receive(at(seconds), bytes);
    return read(seconds);
  }
  std::string read(double seconds) {
    std::string out;
    exchange_.advance(at(seconds), out);
    return out;
  }
  std::optional<double> next_deadline() const {
    const auto d = exchange_.next_deadline();
    if (!d) return std::nullopt;
    return std::chrono::duration<double>(*d - t0_).count();
  }

  Controller& controller() { return controller_; }
  FaultInjection& faults() { return faults_; }

 private:
  SimTime t0_ = SimClock::now();
  FaultInjection faults_;
  Controller controller_;
  TechnoExchange exchange_;
};

ControllerOptions c142() {
  ControllerOptions o;
  o.variant = Variant::c142;
  o.acceleration = 75'000;
  o.home_distance = 1000;
  return o;
}

TEST(TechnoSim, EverythingAnswers4UntilTheAxesAreDefined) {
  Rig rig(c142());
  EXPECT_EQ(rig.send(0, "@0P\r"), "4");
  EXPECT_EQ(rig.send(0.1, "@0A400,9000\r"), "4");
  EXPECT_EQ(rig.send(0.2, "@07\r"), "0");
  EXPECT_EQ(rig.send(0.3, "@0P\r"), "000000000000000000\r");
}

TEST(TechnoSim, AxesDefinitionsOfTheManual) {
  // §11.1 #16: @07, @03 valid; @02, @04, @06, @00 answer 3.
  Rig rig(c142());
  for (const char* bad : {"@02\r", "@04\r", "@06\r", "@00\r", "@08\r"})
    EXPECT_EQ(rig.send(0, bad), "3");
  EXPECT_EQ(rig.send(0, "@03\r"), "0");
  EXPECT_EQ(rig.controller().axes(), 3);
  ControllerOptions it = c142();
  it.variant = Variant::it116g;
  Rig single(it);
  EXPECT_EQ(single.send(0, "@03\r"), "3");
  EXPECT_EQ(single.send(0, "@01\r"), "0");
}

TEST(TechnoSim, CapitalHomeAnswersAtTheEndLowerCaseAtTheStart) {
  // §11.1 #4 and #6: @07, @0R7 (answer at the end), @0M… (end), @0m… (start).
  Rig rig(c142());
  EXPECT_EQ(rig.send(0, "@07\r"), "0");
  EXPECT_EQ(rig.send(0, "@0R7\r"), "");
  // Z, then Y, then X: 1000 steps each at 2000 steps/s with 75000 steps/s² ramps.
  const double per_axis = 1000.0 / 2000 + 2000.0 / 75000;
  EXPECT_EQ(rig.read(3 * per_axis - 0.01), "");
  EXPECT_EQ(rig.read(3 * per_axis + 0.01), "0");
  EXPECT_EQ(rig.send(2, "@0M2700,3000,2000,2000,350,1000,0,1000\r"), "");
  // X and Y together (Y is the longer: 2000 at 2000), then Z down 350 and back.
  const double m = (2000.0 / 2000 + 2000.0 / 75000) + 2 * (350.0 / 1000 + 1000.0 / 75000);
  EXPECT_EQ(rig.read(2 + m - 0.01), "");
  EXPECT_EQ(rig.read(2 + m + 0.01), "0");
  EXPECT_EQ(rig.send(5, "@0P\r"), encode_positions({2700, 2000, 0}) + "\r");
  EXPECT_EQ(rig.send(5, "@0m2700,9000,1000,2000,350,1000,0,1000\r"), "0");
  EXPECT_EQ(rig.read(8), "");
  EXPECT_EQ(rig.send(8, "@0P\r"), encode_positions({2700, 1000, 0}) + "\r");
}

TEST(TechnoSim, PositionsAreTwentyFourBitHex) {
  EXPECT_EQ(encode_positions({16, 8192, -2}), "000010002000FFFFFE");  // §11.1 #8
  EXPECT_EQ(encode_positions({8388607, -8388608, -1}), "7FFFFF800000FFFFFF");
}

TEST(TechnoSim, QueriesDuringACapitalMoveWaitForItsHandshake) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  EXPECT_EQ(rig.send(0, "@0A1000,1000,0,30,0,30,0,30\r"), "");
  EXPECT_EQ(rig.send(0.5, "@0P\r"), "");
  const std::string end = rig.read(1.2);
  EXPECT_EQ(end, "0" + encode_positions({1000, 0, 0}) + "\r");
}

TEST(TechnoSim, QueriesDuringALowerCaseMoveByOption) {
  Rig answer(c142());
  answer.send(0, "@07\r");
  EXPECT_EQ(answer.send(0, "@0a1000,1000,0,30,0,30,0,30\r"), "0");
  const std::string live = answer.send(0.5, "@0P\r");
  EXPECT_EQ(live.size(), 19u);
  EXPECT_NE(live, encode_positions({0, 0, 0}) + "\r");
  auto o = c142();
  o.queries_during_motion = false;
  Rig defer(o);
  defer.send(0, "@07\r");
  EXPECT_EQ(defer.send(0, "@0a1000,1000,0,30,0,30,0,30\r"), "0");
  EXPECT_EQ(defer.send(0.5, "@0P\r"), "");
  EXPECT_EQ(defer.read(1.2), encode_positions({1000, 0, 0}) + "\r");
}

TEST(TechnoSim, ErrorCharacters) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  EXPECT_EQ(rig.send(0, "@0A400,9000\r"), "7");             // wrong count for XYZ
  EXPECT_EQ(rig.send(0, "@0A1,20,0,30,0,30,0,30\r"), "D");  // speed below 30
  EXPECT_EQ(rig.send(0, "@0A1,10001,0,30,0,30,0,30\r"), "D");
  EXPECT_EQ(rig.send(0, "@0A9000000,100,0,30,0,30,0,30\r"), "5");  // beyond ±8,000,000
  EXPECT_EQ(rig.send(0, "@0Ax,100\r"), "5");
  EXPECT_EQ(rig.send(0, "@0R0\r"), "3");
  EXPECT_EQ(rig.send(0, "@0n9\r"), "3");
  EXPECT_EQ(rig.send(0, "@0d100,100\r"), "7");  // one speed per defined axis
  EXPECT_EQ(rig.send(0, "@0e3\r"), "7");
  EXPECT_EQ(rig.send(0, "@0\r"), "\r");  // unexpected end of command
  EXPECT_EQ(rig.send(0, "P\r"), "5");
  EXPECT_EQ(rig.send(0, "@0q\r"), "5");
  EXPECT_EQ(rig.send(0, "@0S\r"), "G");                          // no program stored
  EXPECT_EQ(rig.send(0, "@0M-2000,100,0,30,0,30,0,30\r"), "2");  // behind the home switch
  rig.controller().control("estop", std::vector<std::string>{"on"}, rig.at(0));
  EXPECT_EQ(rig.send(0, "@0R7\r"), "2");
}

TEST(TechnoSim, C142OnlyCommandsAreSyntaxErrorsOnCard4) {
  auto o = c142();
  o.variant = Variant::c116;
  Rig rig(o);
  rig.send(0, "@07\r");
  EXPECT_EQ(rig.send(0, "@0z1\r"), "5");
  EXPECT_EQ(rig.send(0, "@0f-1\r"), "5");
  Rig c(c142());
  c.send(0, "@07\r");
  EXPECT_EQ(c.send(0, "@0z1\r"), "0");
  EXPECT_EQ(c.send(0, "@0f-1\r"), "0");
  EXPECT_EQ(c.send(0, "@0f1\r"), "7");
}

TEST(TechnoSim, CircleOfTheManual) {
  // §11.1 #5: CCW arc of radius 7620 from (7360, 1972); the manual's form has a comma after Y.
  auto o = c142();
  o.home_distance = 20000;
  Rig rig(o);
  EXPECT_EQ(rig.send(0, "@03\r"), "0");
  EXPECT_EQ(rig.send(0, "@0f-1\r"), "0");
  EXPECT_EQ(rig.send(0, "@0Y,9599,1000,314,7360,1972,-1,1\r"), "");
  EXPECT_EQ(rig.read(15), "0");
  EXPECT_EQ(rig.controller().busy(), Controller::Busy::idle);
  // Ending near 68°: X went toward the centre, Y away from it.
  EXPECT_LT(rig.controller().position(0, rig.at(15)), -3000);
  EXPECT_GT(rig.controller().position(1, rig.at(15)), 3000);
}

TEST(TechnoSim, StopRampsDownAndDropsTheCapitalHandshake) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  EXPECT_EQ(rig.send(0, "@0A5000,1000,0,30,0,30,0,30\r"), "");
  EXPECT_EQ(rig.send(1, std::string("\xff\xff")), "");
  EXPECT_EQ(rig.read(10), "");
  EXPECT_EQ(rig.controller().busy(), Controller::Busy::idle);
  const auto x = rig.controller().position(0, rig.at(10));
  EXPECT_GT(x, 900);
  EXPECT_LT(x, 1100);
  EXPECT_EQ(rig.controller().counters().stops, 2u);
}

TEST(TechnoSim, SecondStopDropsABufferedCommand) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  rig.send(0, "@0A5000,1000,0,30,0,30,0,30\r");
  rig.send(0.5, "@0n7\r");  // buffered behind the move
  rig.send(1, std::string("\xff"));
  // One STOP: the buffered zero runs once the ramp has ended.
  EXPECT_EQ(rig.read(2), "0");
  rig.send(2, "@0A5000,1000,0,30,0,30,0,30\r");
  rig.send(2.5, "@0n7\r");
  EXPECT_EQ(rig.send(3, std::string("\xff\xff")), "");
  EXPECT_EQ(rig.read(5), "");  // the second STOP kept it from running
}

TEST(TechnoSim, StopAcknowledgeOption) {
  auto o = c142();
  o.stop_acknowledges = true;
  Rig rig(o);
  rig.send(0, "@07\r");
  rig.send(0, "@0A5000,1000,0,30,0,30,0,30\r");
  rig.send(1, std::string("\xff\xff"));
  EXPECT_EQ(rig.read(2), "0");
}

TEST(TechnoSim, HomingWithoutMechanicsNeedsTwoStops) {
  auto o = c142();
  o.mechanics = false;
  Rig rig(o);
  rig.send(0, "@07\r");
  EXPECT_EQ(rig.send(0, "@0R1\r"), "");
  EXPECT_EQ(rig.read(600), "");  // never answers
  EXPECT_FALSE(rig.next_deadline());
  EXPECT_EQ(rig.send(600, "@0P\r"), "");  // other commands wait until homing ends (p.41)
  rig.send(601, std::string("\xff"));
  EXPECT_EQ(rig.controller().busy(), Controller::Busy::capital);  // once is not enough
  rig.send(601, std::string("\xff"));
  EXPECT_EQ(rig.controller().busy(), Controller::Busy::stopping);
  // The buffered P runs after the ramp; no handshake for R.
  EXPECT_EQ(rig.read(602).size(), 19u);
  EXPECT_EQ(rig.controller().busy(), Controller::Busy::idle);
  rig.controller().control("mechanics", std::vector<std::string>{"on"}, rig.at(602));
  rig.send(602, "@0R1\r");  // 1.2 million steps back to the switch at 2000 steps/s
  EXPECT_EQ(rig.read(1300), "0");
  EXPECT_EQ(rig.controller().position(0, rig.at(1300)), 0);
}

TEST(TechnoSim, ResetHaltsAtOnceWithoutAReply) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  rig.send(0, "@0A5000,1000,0,30,0,30,0,30\r");
  rig.send(0.5, "@0P\r");
  EXPECT_EQ(rig.send(1, std::string("\xfe")), "");
  EXPECT_EQ(rig.read(5), "");  // the buffered P was dropped, the move never answers
  const auto x = rig.controller().position(0, rig.at(5));
  EXPECT_GT(x, 900);
  EXPECT_LT(x, 1000);
  EXPECT_EQ(rig.controller().axes(), 7);  // RESET keeps the definition and the program
  EXPECT_EQ(rig.controller().counters().resets, 1u);
}

TEST(TechnoSim, ZeroAndHomeSpeeds) {
  // §11.1 #15 and #17.
  Rig rig(c142());
  EXPECT_EQ(rig.send(0, "@07\r"), "0");
  EXPECT_EQ(rig.send(0, "@0d 3000,4000,250\r"), "0");
  EXPECT_EQ(rig.send(0, "@05\r"), "0");
  EXPECT_EQ(rig.send(0, "@0d 1000,250\r"), "0");
  EXPECT_EQ(rig.send(0, "@03\r"), "0");
  EXPECT_EQ(rig.send(0, "@0n3\r"), "0");
  rig.send(0, "@0M2700,3000,2000,2000\r");
  rig.read(5);
  EXPECT_EQ(rig.send(5, "@0n3\r"), "0");
  EXPECT_EQ(rig.send(5, "@0P\r"), encode_positions({0, 0, 0}) + "\r");
  rig.send(5, "@0M2700,3000,2000,2000\r");
  rig.read(10);
  EXPECT_EQ(rig.send(10, "@0P\r"), encode_positions({2700, 2000, 0}) + "\r");
}

TEST(TechnoSim, PeekAndPoke) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  EXPECT_EQ(rig.send(0, "@0b65531\r"), "0FF\r");  // open inputs read 1
  rig.controller().control("inputs", std::vector<std::string>{"9"}, rig.at(0));
  EXPECT_EQ(rig.send(0, "@0b65531\r"), "009\r");
  EXPECT_EQ(rig.send(0, "@0B 65529,205\r"), "0");  // §11.2 #14 values
  EXPECT_EQ(rig.send(0, "@0b65529\r"), "0CD\r");
  EXPECT_EQ(rig.send(0, "@0B65530,256\r"), "7");
  EXPECT_EQ(rig.send(0, "@0c2048\r"), "000\r");
}

TEST(TechnoSim, ProgramDownloadAndStart) {
  // §11.2 #7 shortened: @07 @0i <line> 9 @0S (answers at the end of the program).
  Rig rig(c142());
  rig.send(0, "@07\r");
  EXPECT_EQ(rig.send(0, "@0i\r"), "0");
  EXPECT_EQ(rig.send(0, "0 1500,2000,1500,1000,375,1000,-375,1000\r"), "0");
  EXPECT_EQ(rig.send(0, "5 5\r"), "0");
  EXPECT_EQ(rig.send(0, "9\r"), "0");
  EXPECT_EQ(rig.send(0, "@0S\r"), "");
  EXPECT_EQ(rig.read(2.3), "");
  EXPECT_EQ(rig.read(5), "0");
  EXPECT_EQ(rig.send(5, "@0P\r"), encode_positions({1500, 1500, 0}) + "\r");
  EXPECT_EQ(rig.send(5, "@0s\r"), "0");  // lower case: at the start
  EXPECT_EQ(rig.send(5, "@0k\r"), "");   // waits for the program to end
  EXPECT_EQ(rig.read(10), "0");
  EXPECT_EQ(rig.send(10, "@0S\r"), "G");  // erased
}

TEST(TechnoSim, DownloadErrorReturnsToImmediateMode) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  rig.send(0, "@0i\r");
  EXPECT_EQ(rig.send(0, "0 100,2000\r"), "7");
  EXPECT_FALSE(rig.controller().program_mode());
  EXPECT_EQ(rig.send(0, "@0P\r").size(), 19u);
}

TEST(TechnoSim, LfAfterCrAndOtherDevices) {
  Rig rig(c142());
  EXPECT_EQ(rig.send(0, "@07\r\n@0P\r\n"), "0000000000000000000\r");
  EXPECT_EQ(rig.send(0, "@1P\r"), "");
  EXPECT_EQ(rig.controller().counters().other_device, 1u);
  EXPECT_EQ(rig.controller().counters().queries, 1u);
  EXPECT_EQ(rig.controller().counters().commands, 1u);
}

TEST(TechnoSim, ReplyVariants) {
  auto o = c142();
  o.axes = 7;
  o.position_ack = true;
  o.reply_cr = false;
  Rig rig(o);
  EXPECT_EQ(rig.send(0, "@0P\r"), "0000000000000000000");
}

TEST(TechnoSim, WireTimeAtTheEmulatedRate) {
  auto o = c142();
  o.axes = 7;
  ExchangeOptions e;
  e.wire.enabled = true;
  e.wire.timing = WireTiming(9600);
  e.wire.turnaround = 1ms;
  Rig rig(o, e);
  const double ch = 10.0 / 9600;
  // "@0P\r" is 4 characters; the 19-character reply leaves after 1 ms turnaround.
  EXPECT_EQ(rig.send(0, "@0P\r"), "");
  EXPECT_EQ(rig.read(4 * ch + 0.001 + 19 * ch - 0.0005).size() < 19, true);
  EXPECT_EQ(rig.read(4 * ch + 0.001 + 19 * ch + 0.0005).size() > 0, true);
}

TEST(TechnoSim, FaultsApply) {
  auto o = c142();
  o.axes = 7;
  Rig rig(o);
  rig.faults().silence = true;
  EXPECT_EQ(rig.send(0, "@0P\r"), "");
  rig.faults().silence = false;
  rig.faults().truncated_replies = 1;
  EXPECT_EQ(rig.send(0, "@0P\r"), "000000000");
  rig.faults().garbage_replies = 1;
  const std::string g = rig.send(0, "@0n7\r");
  EXPECT_EQ(g.size(), 1u);
}

TEST(TechnoSim, ControlVerbs) {
  Rig rig(c142());
  rig.send(0, "@07\r");
  rig.send(0, "@0P\r");
  const auto counters = rig.controller().control("counters", {}, rig.at(0));
  ASSERT_TRUE(counters);
  EXPECT_EQ(*counters,
            "ok counters lines=2 queries=1 commands=1 stops=0 resets=0 other_device=0 last=@0P");
  EXPECT_EQ(*rig.controller().control("power-cycle", {}, rig.at(0)), "ok power-cycle");
  EXPECT_EQ(rig.send(0, "@0P\r"), "4");
  EXPECT_EQ(*rig.controller().control("mechanics", std::vector<std::string>{"x"}, rig.at(0)),
            "error: usage: mechanics on|off");
  EXPECT_FALSE(rig.controller().control("nope", {}, rig.at(0)));
  const auto state = rig.controller().control("state", {}, rig.at(0));
  EXPECT_EQ(state->rfind("ok state axes=0 busy=idle", 0), 0u) << *state;
}

}  // namespace
}  // namespace fieldgate::sim::techno
