// The CN0170 chain simulator without a PTY, on injected time: chain rules of manual p.13–15,
// auto-baud, kill relay, queues and the motion physics.
#include <gtest/gtest.h>

#include "sim/centent/daisy_chain.hpp"

namespace fieldgate::sim::centent {
namespace {

using namespace std::chrono_literals;

class SimChain : public ::testing::Test {
 protected:
  void make(std::vector<int> units, ChainOptions o = {}) {
    o.units = std::move(units);
    chain = std::make_unique<DaisyChain>(o, t0);
  }
  // Sends host lines (each ends with CR) at `at` and returns everything the chain sent back.
  std::string send(std::string_view lines, SimTime at) {
    std::string out;
    std::string pending(lines);
    while (const auto n = DaisyChain::frame(pending)) {
      out += chain->handle(pending.substr(0, n), at).bytes;
      pending.erase(0, n);
    }
    return out;
  }
  std::string send(std::string_view lines) { return send(lines, t0); }
  std::string control(std::string_view verb, std::vector<std::string> args, SimTime at) {
    return chain->control(verb, args, at).value_or("?");
  }

  SimTime t0 = SimTime{} + 1h;
  std::unique_ptr<DaisyChain> chain;
};

TEST_F(SimChain, SelectedUnitTrapsAndRepliesWithItsPrefix) {
  make({0, 1, 2});
  EXPECT_EQ(send(".U1\rXP?;YP?\r"), "1X=00000000h\r1Y=00000000h\r");
  EXPECT_EQ(send(".U0\rM?\r"), "M1\r");  // unit 0: no prefix
  EXPECT_EQ(chain->lines_trapped(0), 1u);
  EXPECT_EQ(chain->lines_trapped(1), 1u);
  EXPECT_EQ(chain->stats().selections, 2u);
  EXPECT_EQ(chain->stats().selections_of[1], 1u);
}

TEST_F(SimChain, V16RelativeAssignmentAndRenumbering) {
  make({9, 9, 9, 9});
  EXPECT_EQ(send(".U=0\r.U+1=1\r.U+2=2\r.U+3=3\r.U2=5\r"), "");
  // V18: replies in physical chain order.
  EXPECT_EQ(send(".U?\r"), "[U0]\r[U1]\r[U5]\r[U3]\r");
}

TEST_F(SimChain, DuplicateNumberNearerUnitTrapsEverything) {
  make({0, 1, 1});
  send(".U1\rX=0400H\r");
  EXPECT_EQ(send(".U?\r"), "[U0]\r[U1]\r[U1]\r");
  EXPECT_EQ(chain->lines_trapped(1), 1u);
  EXPECT_EQ(chain->lines_trapped(2), 0u);
  EXPECT_EQ(chain->unit_at(1).queued() + (chain->unit_at(1).moving('X', t0 + 10ms) ? 1 : 0), 1u);
  EXPECT_FALSE(chain->unit_at(2).moving('X', t0 + 10ms));
}

TEST_F(SimChain, UnknownSelectionPassesOutTheLastPort) {
  make({0, 1});
  EXPECT_EQ(send(".U7\rXP?\r"), "");
  EXPECT_EQ(chain->stats().passed_through, 2u);  // .U7 itself and XP?
}

TEST_F(SimChain, V5RejectedInstructionIsEchoed) {
  make({0, 2});
  EXPECT_EQ(send(".U2\rXY?;XP?\r"), "2\"XY?\" ?\r2X=00000000h\r");
  EXPECT_EQ(send(".U2\rX=0ffh\r"), "2\"X=0ffh\" ?\r") << "hex needs an upper-case H";
}

TEST_F(SimChain, QueryFormatsOfTheManual) {
  make({0});
  send("YV=,13601.25;Y++\r");
  const std::string running = send("YV?;XA?;XC?;A\\X?;P?;Y/X?\r", t0 + 5s);
  EXPECT_EQ(running, "YV=0D485h\rXA=009Ch\rXC=L\rA\\X=80h\rP= 00h\rY/X=00000000h\r");
  send("XA=3000;XC3;Y/X=.5\r");
  EXPECT_EQ(send("XA?;XC?;Y/X?\r"), "XA=002Fh\rXC=3\rY/X=80000000h\r");
  send("T=13:32;D=01/02/97\r");
  EXPECT_EQ(send("T?;D?\r", t0 + 11s), "13:32.11\r01/02/97\r");
}

TEST_F(SimChain, AbsoluteMoveReachesTargetWithTrapezoid) {
  make({0});
  // 1000 steps at 2000 steps/s max, 156 × 64 = 9984 steps/s²: 0.2 s ramps, 0.3 s at speed.
  send("X=1000\r");
  EXPECT_EQ(send("XP?\r", t0 + 100ms).substr(0, 2), "X+");
  EXPECT_EQ(send("XP?\r", t0 + 650ms).substr(0, 2), "X+");
  EXPECT_EQ(send("XP?\r", t0 + 750ms), "X=000FA000h\r");
  send("X=0\r", t0 + 1s);
  EXPECT_EQ(send("XP?\r", t0 + 1100ms).substr(0, 2), "X-");
}

TEST_F(SimChain, MovesOfOneAxisQueueAndLinkedMovesWaitForBoth) {
  make({0});
  send("X+1000;X+1000;Y+10\r");
  // Y runs at once; the second X move waits for the first.
  const auto at1s = send("XP?;YP?\r", t0 + 1s);
  EXPECT_EQ(at1s.substr(0, 2), "X+") << at1s;
  EXPECT_NE(at1s.find("\rY=00002800h\r"), std::string::npos) << at1s;
  EXPECT_EQ(send("XP?\r", t0 + 2s), "X=001F4000h\r");
}

TEST_F(SimChain, LinearInterpolationEndsBothAxesTogether) {
  make({0});
  send("XYV=200,1000;X=3000,Y=4000\r");
  // 5000 steps of path at 1000 steps/s: both axes still moving at 4.9 s, both done by 5.2 s.
  EXPECT_EQ(send("XP?;YP?\r", t0 + 4900ms).substr(0, 2), "X+");
  const auto end = send("XP?;YP?\r", t0 + 5300ms);
  EXPECT_EQ(end, "X=002EE000h\rY=003E8000h\r");
}

TEST_F(SimChain, HomeMovesToTheSwitchAndZeroesThePosition) {
  make({0});
  send("XP=500;XH\r");
  EXPECT_EQ(send("XP?\r", t0 + 100ms).substr(0, 2), "X-");
  EXPECT_EQ(send("XP?\r", t0 + 5s), "X=00000000h\r");
}

TEST_F(SimChain, SpeedControlUntilQuit) {
  make({0});
  send("X--500\r");
  EXPECT_EQ(send("XV?\r", t0 + 1s), "XV=07D0h\r");  // 500 steps/s = 2000 quarter steps
  send("Q\r", t0 + 1s);
  EXPECT_EQ(send("XV?\r", t0 + 2s), "XV=0000h\r");
  EXPECT_EQ(send("XP?\r", t0 + 2s).substr(0, 2), "X=");
}

TEST_F(SimChain, KillIsRelayedDownstreamOnly) {
  make({0, 1, 2});
  send(".U0\rX++\r.U1\rX++\r.U2\rX++\r");
  send(".U1\rK\r", t0 + 1s);
  EXPECT_TRUE(chain->unit_at(0).moving('X', t0 + 2s)) << "upstream of the selected unit";
  EXPECT_FALSE(chain->unit_at(1).moving('X', t0 + 2s));
  EXPECT_FALSE(chain->unit_at(2).moving('X', t0 + 2s));
  ChainOptions o;
  o.kill_acts_upstream = true;
  make({0, 1, 2}, o);
  send(".U0\rX++\r.U1\rX++\r");
  send(".U1\rK\r", t0 + 1s);
  EXPECT_FALSE(chain->unit_at(0).moving('X', t0 + 2s));
}

TEST_F(SimChain, ResetUnitAnswersItsAutobaudCr) {
  make({0, 1, 2});
  EXPECT_EQ(control("reset", {"1"}, t0), "ok reset 1");
  EXPECT_EQ(send("\r.U2\rXP?\r"), "U1\r2X=00000000h\r");
  // Selected itself after the power-up until .U2 arrived.
  EXPECT_EQ(control("chain", {}, t0), "ok chain 0,1,2");
}

TEST_F(SimChain, ResetUnitWithoutCrFirstLosesItsBaudRate) {
  make({0, 1, 2});
  control("reset", {"1"}, t0);
  EXPECT_EQ(send(".U2\rXP?\r"), "");
  EXPECT_EQ(control("chain", {}, t0), "ok chain 0,1(failed),2");
  EXPECT_EQ(send("\r.U0\rM?\r"), "M1\r") << "units before it still work";
  ChainOptions o;
  o.strict_autobaud = false;
  make({0, 1, 2}, o);
  control("reset", {"1"}, t0);
  EXPECT_EQ(send(".U2\r"), "U1\r") << "locks on the first CR; that line is lost";
  EXPECT_EQ(send("XP?\r"), "1X=00000000h\r") << "and it selected itself";
}

TEST_F(SimChain, PowerUpChainAnswersInTurn) {
  ChainOptions o;
  o.power_up = true;
  make({0, 1, 2}, o);
  EXPECT_EQ(send("\r"), "U0\rU1\rU2\r");
  ChainOptions p;
  p.power_up = true;
  p.prefix_unit_messages = true;
  make({0, 1}, p);
  EXPECT_EQ(send("\r.U?\r"), "U0\r1U1\r[U0]\r1[U1]\r");
}

TEST_F(SimChain, UnpoweredUnitCutsOffTheRestOfTheChain) {
  make({0, 1, 2});
  control("unit-off", {"1"}, t0);
  EXPECT_EQ(send(".U?\r"), "[U0]\r");
  EXPECT_EQ(send(".U2\rM?\r"), "");
  control("unit-on", {"1"}, t0);
  // Unit messages are unprefixed by default (as printed on p.1 and p.15).
  EXPECT_EQ(send("\r.U?\r"), "U1\r[U0]\r[U1]\r[U2]\r");
}

TEST_F(SimChain, OverflowWarningAndQueueEmpty) {
  make({0, 3});
  send(".U3\rM1\\-\r");
  std::string lines;
  // The first move runs at once; 26 waiting fill 8 staging places and 18 of the 20 queue places.
  for (int i = 0; i < 27; ++i) lines += "X+10\r";
  EXPECT_EQ(send(lines), "3Q*\r");
  // Each 10-step move takes ~63 ms: the queue drains and *Q follows, once.
  EXPECT_EQ(send(".U3\rM?\r", t0 + 3s), "3*Q\r3M1\r");
  EXPECT_EQ(send("M?\r", t0 + 4s), "3M1\r");
}

TEST_F(SimChain, PositionTriggerAtEveryMoveEnd) {
  make({0, 1});
  send(".U1\rXP+;X+10;X+10\r");
  EXPECT_EQ(send("M?\r", t0 + 2s), "1XP\r1XP\r1M1\r");
}

TEST_F(SimChain, ProgramModeStoresInstructions) {
  make({0});
  send("M2\rX+100\rXP?\r");
  EXPECT_EQ(send("M?\r"), "M2\r");
  EXPECT_EQ(chain->unit_at(0).program().size(), 2u);
  EXPECT_FALSE(chain->unit_at(0).moving('X', t0 + 10ms));
}

TEST_F(SimChain, ControlCommands) {
  make({0, 1});
  EXPECT_EQ(control("emit", {"1", "Q*"}, t0), "ok emit 1");
  EXPECT_EQ(send(".U0\rM?\r"), "1Q*\rM1\r");
  EXPECT_EQ(control("input", {"1", "2", "1"}, t0), "ok input");
  EXPECT_EQ(control("analog", {"1", "X", "192"}, t0), "ok analog");
  EXPECT_EQ(control("aux", {"1", "0x3c"}, t0), "ok aux");
  EXPECT_EQ(send(".U1\rP2?;A\\X?;P?\r"), "1P2=1\r1A\\X=C0h\r1P= 3Ch\r");
  send("P3=1\r");
  EXPECT_EQ(control("position", {"1"}, t0),
            "ok position unit=1 x=0 y=0 x_moving=0 y_moving=0 mode=1 out1=1 out2=0");
  EXPECT_EQ(control("stats", {}, t0).substr(0, 30), "ok stats selections=2 lines=5 ");
  EXPECT_EQ(control("number", {"#2", "0"}, t0), "ok number #2 0");
  EXPECT_EQ(control("chain", {}, t0), "ok chain 0,0");
  EXPECT_EQ(control("reset", {"7"}, t0), "error: no unit 7");
  EXPECT_FALSE(chain->control("fly", {}, t0));
}

TEST_F(SimChain, UnitListFromTheCli) {
  EXPECT_EQ(parse_unit_list("0,1,5,3"), (std::vector<int>{0, 1, 5, 3}));
  EXPECT_THROW(parse_unit_list("0,12"), std::invalid_argument);
}

}  // namespace
}  // namespace fieldgate::sim::centent
