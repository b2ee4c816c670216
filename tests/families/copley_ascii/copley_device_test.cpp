#include <gtest/gtest.h>

#include "tests/families/copley_ascii/copley_bench.hpp"
#include "tests/harness/exchange_table.hpp"

namespace fieldgate::sim::copley::test {
namespace {

using fieldgate::test::Exchange;
using fieldgate::test::expect_replies;

using namespace std::chrono_literals;

constexpr std::int64_t kDisabled = bit(12) | bit(15);

TEST(CopleyErrors, CommandLevel) {
  CopleyBench amp;
  const std::vector<Exchange> transcript = {
      {"x r0x30", "e 3\r"},
      {"s r0x30", "e 4\r"},
      {"s r0x6b 1 2 3", "e 4\r", "0x6b takes nine values"},
      {"s r0x30 1 2", "e 5\r"},
      {"s r0x72 258", "e 4\r"},
      {"s r0x72 258 0 0", "e 5\r"},
      {"g r0x31", "e 9\r"},
      {"g r0x1000", "e 9\r"},
      {"s r0x30 0x100000000", "e 10\r"},
      {"s r0x30 -2147483649", "e 10\r"},
      {"s r0x90 4800", "e 10\r"},
      {"s r0x90 230400", "e 10\r"},
      {"i r0 0x100000000", "e 10\r"},
      {"s r0x32 5", "e 11\r", "monitor variable"},
      {"s r0xa0 0", "e 11\r", "status register"},
      {"s r0xc9 0", "e 11\r"},
      {"s r0x24 99", "e 14\r"},
      {"s r0x24 31", "e 14\r", "a servo amplifier has no microstep states"},
      {"g f0x17", "e 15\r"},
      {"g f0xa0", "e 15\r"},
      {"s f0x90 19200", "e 15\r", "0x90 is RAM only"},
      {"s f0x32 1", "e 15\r"},
      {"c r0x32", "e 15\r"},
      {"c f0x90", "e 15\r"},
      {"c r0x31", "e 9\r"},
      {"128 g r0x32", "e 31\r"},
      {"5 g r0x32", "e 32\r", "no node 5 on the CAN bus"},
      {".b g r0x32", "e 33\r", "single-axis amplifier"},
      {"g r0x32 ", "e 33\r"},
      {"g r0x32\n", "e 33\r", "LF is not part of the protocol"},
      {std::string(300, 'g'), "e 1\r"},
  };
  expect_replies(amp, transcript);
}

TEST(CopleyErrors, StepperAcceptsMicrostepStates) {
  NetworkOptions options;
  options.stepper = true;
  CopleyBench amp(options);
  EXPECT_EQ(amp.send("s r0x24 31"), "ok\r");
  EXPECT_EQ(amp.send("s r0x24 21"), "ok\r");
}

TEST(CopleyErrors, TrajectoryLimits) {
  CopleyBench amp;
  EXPECT_EQ(amp.send("t 1"), "e 14\r") << "disabled";
  EXPECT_EQ(amp.send("t 2"), "e 14\r");
  EXPECT_EQ(amp.send("t 0"), "ok\r") << "abort is always accepted";
  amp.send("s r0x24 11");
  EXPECT_EQ(amp.send("t 1"), "e 14\r") << "velocity mode has no trajectory";
  EXPECT_EQ(amp.send("t 2"), "e 14\r") << "homing needs 21 or 31";
  amp.send("s r0x24 21");
  amp.send("s r0xca 100000");
  // One bad trajectory parameter at a time refuses the move with its error, then is repaired.
  struct BadParameter {
    const char* variable;
    const char* bad;
    const char* good;
    const char* error;
  };
  for (const BadParameter& p : std::vector<BadParameter>{
           {"r0xcb", "0", "10000", "e 19\r"},
           {"r0xcc", "0", "10000", "e 20\r"},
           {"r0xcd", "-1", "10000", "e 21\r"},
           {"r0xc8", "3", "1", "e 25\r"},
           {"r0xce", "0", "1000", "e 22\r"},
       }) {
    SCOPED_TRACE(std::string(p.variable) + " " + p.bad);
    amp.send("s " + std::string(p.variable) + " " + p.bad);
    EXPECT_EQ(amp.send("t 1"), p.error);
    amp.send("s " + std::string(p.variable) + " " + p.good);
  }
  EXPECT_EQ(amp.send("t 1"), "ok\r") << "S-curve, run as a trapezoid";
  EXPECT_EQ(amp.send("t 1", 1), "e 18\r") << "S-curve moves cannot be updated";
  EXPECT_EQ(amp.send("t 2", 1), "e 18\r") << "no homing while moving";
  amp.send("s r0xc8 0", 1);
  EXPECT_EQ(amp.send("t 1", 1), "e 18\r") << "nor replaced by a trapezoid";
}

TEST(CopleyVariables, RamFlashAndReset) {
  CopleyBench amp;
  EXPECT_EQ(amp.value("g r0x30"), 1000);
  EXPECT_EQ(amp.send("s f0x30 5"), "ok\r");
  EXPECT_EQ(amp.value("g r0x30"), 1000) << "flash writes leave RAM alone";
  EXPECT_EQ(amp.value("g f0x30"), 5);
  EXPECT_EQ(amp.send("c f0x30"), "ok\r");
  EXPECT_EQ(amp.value("g r0x30"), 5);
  amp.send("s r0x30 7");
  EXPECT_EQ(amp.send("c r0x30"), "ok\r");
  EXPECT_EQ(amp.value("g f0x30"), 7);
  amp.send("s r0x30 9");
  amp.send("i r3 42");
  EXPECT_EQ(amp.exchange("r").bytes, "");
  EXPECT_EQ(amp.value("g r0x30"), 7) << "RAM reloaded from flash";
  EXPECT_EQ(amp.send("i r3"), "r 0\r") << "CVM registers are RAM";
  EXPECT_EQ(amp.values("g r0x72"), (std::vector<std::int64_t>{0, 0}));
  EXPECT_EQ(amp.send("s r0x72 258 0"), "ok\r");
  EXPECT_EQ(amp.values("g r0x72"), (std::vector<std::int64_t>{258, 0}));
  EXPECT_EQ(amp.send("g r48"), "v 7\r") << "decimal variable IDs";
}

TEST(CopleyVariables, DesiredStateFromFlashAtPowerUp) {
  CopleyBench amp;
  amp.send("s f0x24 21");
  EXPECT_EQ(amp.value("g r0xa0"), kDisabled);
  amp.exchange("r");
  EXPECT_EQ(amp.value("g r0x24"), 21);
  EXPECT_EQ(amp.value("g r0xa0"), 0) << "comes up enabled";
}

TEST(CopleyVariables, BaudRate) {
  CopleyBench amp(nodes({0, 3}));
  EXPECT_NEAR(static_cast<double>(amp.value("g r0x90")), 9600, 10);
  DeviceReply reply = amp.exchange("s r0x90 115200");
  EXPECT_EQ(reply.new_baud, 115200u);
  EXPECT_NEAR(static_cast<double>(amp.value("g r0x90")), 115200, 1152);
  reply = amp.exchange("3 s r0x90 57600");
  EXPECT_EQ(reply.bytes, "ok\r");
  EXPECT_FALSE(reply.new_baud) << "a remote node's serial port is not the link";
  reply = amp.exchange("r");
  EXPECT_EQ(reply.new_baud, 9600u);
  EXPECT_NEAR(static_cast<double>(amp.value("g r0x90")), 9600, 10);
}

TEST(CopleyStatus, EnableDisable) {
  CopleyBench amp;
  EXPECT_EQ(amp.value("g r0xa0"), kDisabled);
  amp.send("s r0x24 21");
  EXPECT_EQ(amp.value("g r0xa0"), 0);
  EXPECT_EQ(amp.value("g r0xc9"), 0);
  amp.send("s r0x24 0");
  EXPECT_EQ(amp.value("g r0xa0"), kDisabled);
}

TEST(CopleyStatus, FaultsLatchAndClearByWritingOnes) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  EXPECT_EQ(amp.control("fault 0 512"), "ok fault 0 512");
  EXPECT_EQ(amp.value("g r0xa4"), 512);
  EXPECT_EQ(amp.value("g r0xa0"), bit(22) | bit(15));
  EXPECT_EQ(amp.send("t 1"), "e 14\r") << "no moves while faulted";
  amp.send("s r0xa4 1");  // bit 0 is not set: nothing changes
  EXPECT_EQ(amp.value("g r0xa4"), 512);
  amp.send("s r0xa4 512");
  EXPECT_EQ(amp.value("g r0xa4"), 0);
  EXPECT_EQ(amp.value("g r0xa0"), 0);
  EXPECT_EQ(amp.send("t 1"), "ok\r");

  amp.control("fault 0 0x3");
  amp.send("s r0xa4 3");
  EXPECT_EQ(amp.value("g r0xa4"), 3) << "bits 0 and 1 are fatal";
  amp.exchange("r");
  EXPECT_EQ(amp.value("g r0xa4"), 3) << "and survive a reset";
}

TEST(CopleyStatus, FaultStopsAMove) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  amp.send("s r0xca 100000");
  amp.send("t 1");
  amp.control("fault 0 512", 1);
  const std::int64_t position = amp.value("g r0x32", 1);
  EXPECT_EQ(amp.value("g r0x32", 5), position);
  EXPECT_EQ(amp.value("g r0xa0", 5) & bit(27), 0);
}

TEST(CopleyMotion, PollerSeesAMoveProgressAndComplete) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  amp.send("s r0xca 5000");
  amp.send("s r0xcb 20000");  // 2000 counts/s
  amp.send("s r0xcc 1000");   // 10000 counts/s^2
  amp.send("s r0xcd 1000");
  ASSERT_EQ(amp.send("t 1"), "ok\r");
  std::int64_t last = -1;
  double t = 0.05;
  for (; t < 10; t += 0.05) {
    const std::int64_t position = amp.value("g r0x32", t);
    EXPECT_GE(position, last);
    last = position;
    const std::int64_t status = amp.value("g r0xa0", t);
    if ((status & bit(27)) == 0) break;
    EXPECT_NE(amp.value("g r0xc9", t) & bit(15), 0);
    EXPECT_GT(amp.value("g r0x3d", t), 0);
  }
  EXPECT_NEAR(t, 2.7, 0.06) << "0.2 s up, 2.3 s cruise, 0.2 s down";
  EXPECT_EQ(amp.value("g r0x32", t), 5000);
  EXPECT_EQ(amp.value("g r0x3d", t), 5000);
  EXPECT_EQ(amp.value("g r0x35", t), 0);
  EXPECT_EQ(amp.value("g r0x18", t), 0);
  EXPECT_EQ(amp.value("g r0xc9", t), 0);
}

TEST(CopleyMotion, MonitorsDuringAMove) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  amp.send("s r0xca 100000");
  amp.send("s r0xcb 20000");  // 2000 counts/s
  amp.send("s r0xcc 1000");   // 10000 counts/s^2
  amp.send("t 1");
  EXPECT_EQ(amp.value("g r0x3c", 0.1), 1000) << "profile acceleration, 10 counts/s^2";
  EXPECT_GT(amp.value("g r0x0c", 0.1), 0) << "accelerating takes current";
  EXPECT_EQ(amp.value("g r0x2c", 1), 20000);
  EXPECT_EQ(amp.value("g r0x18", 1), 20000);
  EXPECT_EQ(amp.value("g r0x35", 1), 2) << "servo lag of 1 ms at 2000 counts/s";
  EXPECT_EQ(amp.value("g r0x3d", 1) - amp.value("g r0x32", 1), 2);
  EXPECT_EQ(amp.value("g r0x17", 1), amp.value("g r0x32", 1));
  EXPECT_EQ(amp.value("g r0x1e", 1), 480);
  EXPECT_GE(amp.value("g r0x20", 1), 30);
  const std::int64_t angle = amp.value("g r0xb0", 1);
  EXPECT_GE(angle, 0);
  EXPECT_LT(angle, 360);
}

TEST(CopleyMotion, RelativeMovesAddUp) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  amp.send("s r0xc8 256");
  amp.send("s r0xca 300");
  amp.send("t 1");
  amp.send("t 1", 0.01);  // still moving: counts from the end of the first move
  EXPECT_EQ(amp.value("g r0x32", 5), 600);
  amp.send("s r0xca -1000", 5);
  amp.send("t 1", 5);
  EXPECT_EQ(amp.value("g r0x32", 10), -400);
}

TEST(CopleyMotion, AbortKeepsTheAmplifierEnabled) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  amp.send("s r0xca 100000");
  amp.send("t 1");
  EXPECT_EQ(amp.send("t 0", 1), "ok\r");
  EXPECT_NE(amp.value("g r0xc9", 1.0001) & bit(15), 0) << "stopping ramp";
  EXPECT_EQ(amp.value("g r0xc9", 2), bit(14));
  EXPECT_EQ(amp.value("g r0xa0", 2), 0);
  amp.send("t 1", 2);
  EXPECT_EQ(amp.value("g r0xc9", 2) & bit(14), 0) << "cleared by the next move";
}

TEST(CopleyMotion, JogInPositionMode) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  amp.send("s r0xc8 2");
  amp.send("s r0xca -1");
  amp.send("s r0xcb 10000");  // 1000 counts/s
  ASSERT_EQ(amp.send("t 1"), "ok\r");
  EXPECT_EQ(amp.value("g r0x18", 2), -10000);
  EXPECT_NE(amp.value("g r0xa0", 100) & bit(27), 0) << "runs until stopped";
  amp.send("s r0xcb 0", 100);
  ASSERT_EQ(amp.send("t 1", 100), "ok\r");
  EXPECT_EQ(amp.value("g r0x18", 101), 0);
  EXPECT_EQ(amp.value("g r0xa0", 101), 0);
}

TEST(CopleyMotion, SoftwareLimits) {
  CopleyBench amp;
  amp.send("s r0xb8 1000");
  amp.send("s r0xb9 -1000");
  amp.send("s r0x24 21");
  amp.send("s r0xca 5000");
  amp.send("t 1");
  EXPECT_EQ(amp.value("g r0x32", 5), 1000);
  EXPECT_EQ(amp.value("g r0xa0", 5), bit(16));
  amp.send("s r0xc8 2", 5);
  amp.send("s r0xca -1", 5);
  amp.send("t 1", 5);
  EXPECT_EQ(amp.value("g r0x32", 10), -1000) << "a jog stops at the limit";
  EXPECT_EQ(amp.value("g r0xa0", 10), bit(17));
}

TEST(CopleyHoming, SetCurrentPositionAsHome) {
  CopleyBench amp;
  amp.send("s r0xc2 512");
  amp.send("s r0xc6 -250");
  amp.send("s r0x24 21");
  EXPECT_EQ(amp.send("t 2"), "ok\r");
  EXPECT_EQ(amp.value("g r0xc9"), bit(12));
  EXPECT_EQ(amp.value("g r0x32"), -250);
}

TEST(CopleyHoming, NegativeMethodTravelsNegative) {
  CopleyBench amp;
  amp.send("s r0xc2 560");  // next index, negative
  amp.send("s r0x24 21");
  amp.send("t 2");
  EXPECT_LT(amp.value("g r0x32", 0.2), 0);
  EXPECT_EQ(amp.value("g r0xc9", 3), bit(12));
}

TEST(CopleyHoming, FailuresSetBit11) {
  CopleyBench amp;
  amp.send("s r0x24 21");
  amp.send("s r0xc2 1");  // not a homing method
  EXPECT_EQ(amp.send("t 2"), "ok\r");
  EXPECT_EQ(amp.value("g r0xc9"), bit(11));
  amp.send("s r0xc2 544");
  amp.send("t 2");
  EXPECT_EQ(amp.value("g r0xc9", 0.1), bit(13)) << "a new attempt clears bit 11";
  amp.send("t 0", 0.1);
  EXPECT_EQ(amp.value("g r0xc9", 1), bit(11) | bit(14)) << "aborted homing failed";
  amp.send("t 2", 1);
  amp.send("s r0x24 0", 1.1);
  EXPECT_EQ(amp.value("g r0xc9", 2), bit(11)) << "disabling ends homing as failed";
}

TEST(CopleyModes, VelocityModeFollowsNewCommands) {
  CopleyBench amp;
  amp.send("s r0x36 0");  // 0 = unlimited
  amp.send("s r0x37 0");
  amp.send("s r0x2f -5000");
  amp.send("s r0x24 11");
  EXPECT_EQ(amp.value("g r0x18", 0.001), -5000);
  amp.send("s r0x3a 30000", 1);  // limit 300 counts/s (0.01 counts/s units)
  EXPECT_EQ(amp.value("g r0x18", 1.001), -3000);
}

TEST(CopleyNetwork, GatewayForwardsByNodeId) {
  NetworkOptions options = nodes({0, 3, 5});
  options.forward_latency = 300us;
  CopleyBench amp(options);
  amp.send("3 s r0x30 33");
  EXPECT_EQ(amp.value("3 g r0x30"), 33);
  EXPECT_EQ(amp.value("5 g r0x30"), 1000);
  EXPECT_EQ(amp.value("g r0x30"), 1000);
  EXPECT_EQ(amp.value("0 g r0x30"), 1000) << "node 0 is the gateway itself";
  EXPECT_EQ(amp.exchange("3 g r0x30").extra_delay, 300us);
  EXPECT_EQ(amp.exchange("g r0x30").extra_delay, 0us);
}

TEST(CopleyNetwork, RemoteResetAnswersE32AndReloadsFlash) {
  CopleyBench amp(nodes({0, 3}));
  amp.send("3 s r0x30 33");
  const DeviceReply reply = amp.exchange("3 r");
  EXPECT_EQ(reply.bytes, "e 32\r");
  EXPECT_FALSE(reply.new_baud);
  EXPECT_EQ(amp.value("3 g r0x30"), 1000);
  EXPECT_EQ(amp.send("9 r"), "e 32\r") << "an absent node also answers e 32";
}

TEST(CopleyNetwork, BootTimeMakesAResetNodeDeaf) {
  NetworkOptions options = nodes({0, 3});
  options.boot_time = 100ms;
  CopleyBench amp(options);
  amp.send("3 r", 1);
  EXPECT_EQ(amp.send("3 g r0x30", 1.05), "e 32\r");
  EXPECT_EQ(amp.send("3 g r0x30", 1.15), "v 1000\r");
  amp.send("r", 2);
  EXPECT_EQ(amp.send("g r0x30", 2.05), "") << "the gateway booting: no reply at all";
  EXPECT_EQ(amp.send("g r0x30", 2.15), "v 1000\r");
}

TEST(CopleyNetwork, ControlChannelCommands) {
  CopleyBench amp(nodes({0, 3}));
  EXPECT_EQ(amp.control("node-off 3"), "ok node-off 3");
  EXPECT_EQ(amp.send("3 g r0x32"), "e 32\r");
  EXPECT_EQ(amp.send("g r0x32"), "v 0\r");
  EXPECT_EQ(amp.control("node-on 3"), "ok node-on 3");
  EXPECT_EQ(amp.send("3 g r0x32"), "v 0\r");
  EXPECT_EQ(amp.control("node-off 0"), "ok node-off 0");
  EXPECT_EQ(amp.send("g r0x32"), "") << "gateway off: total silence";
  EXPECT_EQ(amp.send("3 g r0x32"), "");
  amp.control("node-on 0");

  EXPECT_EQ(amp.control("inputs 3 33"), "ok inputs 3 33");
  EXPECT_EQ(amp.value("3 g r0xa6"), 33);
  EXPECT_EQ(amp.control("fault 3 512"), "ok fault 3 512");
  EXPECT_EQ(amp.value("3 g r0xa4"), 512);

  amp.send("s r0x30 1");
  EXPECT_EQ(amp.control("reset 0"), "ok reset 0");
  EXPECT_EQ(amp.last_control_baud, 9600u);
  EXPECT_EQ(amp.value("g r0x30"), 1000);
  EXPECT_EQ(amp.control("reset 3"), "ok reset 3");
  EXPECT_FALSE(amp.last_control_baud);
  EXPECT_EQ(amp.value("3 g r0xa4"), 0);

  EXPECT_EQ(amp.control("node-off 4").rfind("error:", 0), 0u);
  EXPECT_EQ(amp.control("fault 3.b 1").rfind("error:", 0), 0u);
  EXPECT_EQ(amp.control("fault 3 x").rfind("error:", 0), 0u);
  EXPECT_EQ(amp.control("node-off").rfind("error:", 0), 0u);
  EXPECT_EQ(amp.control("silence on"), "(not a family command)");
}

TEST(CopleyNetwork, MultiAxisNodes) {
  NetworkOptions options = nodes({0, 2});
  parse_axes("0:2,2:3", options);
  CopleyBench amp(options);
  amp.send(".b s r0x30 22");
  EXPECT_EQ(amp.value(".b g r0x30"), 22);
  EXPECT_EQ(amp.value(".a g r0x30"), 1000);
  EXPECT_EQ(amp.value("g r0x30"), 1000) << "no axis letter: axis a";
  EXPECT_EQ(amp.send(".c g r0x30"), "e 33\r");
  EXPECT_EQ(amp.value("2.c g r0x30"), 1000);
  EXPECT_EQ(amp.control("fault 2.c 4"), "ok fault 2.c 4");
  EXPECT_EQ(amp.value("2.c g r0xa4"), 4);
  EXPECT_EQ(amp.value("2.b g r0xa4"), 0);
}

TEST(CopleyNetwork, CvmRegisters) {
  CopleyBench amp(nodes({0, 8}));
  EXPECT_EQ(amp.send("i r31 -7"), "ok\r");
  EXPECT_EQ(amp.send("i r31"), "r -7\r");
  EXPECT_EQ(amp.send("i r5 0xffffffff"), "ok\r");
  EXPECT_EQ(amp.send("i r5"), "r -1\r");
  EXPECT_EQ(amp.network.cvm_register(0, 31), -7);
  EXPECT_EQ(amp.send("8 i r31"), "r 0\r");
}

TEST(CopleyCli, NodeAndAxisLists) {
  EXPECT_EQ(parse_node_list("3,5"), (std::vector<int>{0, 3, 5}));
  EXPECT_EQ(parse_node_list("0,3,3"), (std::vector<int>{0, 3}));
  EXPECT_THROW(parse_node_list("128"), std::invalid_argument);
  EXPECT_THROW(parse_node_list("3,,5"), std::invalid_argument);
  NetworkOptions options;
  parse_axes("2", options);
  EXPECT_EQ(options.default_axes, 2);
  parse_axes("0:1,7:3", options);
  EXPECT_EQ(options.axes.at(0), 1);
  EXPECT_EQ(options.axes.at(7), 3);
  EXPECT_THROW(parse_axes("4", options), std::invalid_argument);
}

}  // namespace
}  // namespace fieldgate::sim::copley::test
